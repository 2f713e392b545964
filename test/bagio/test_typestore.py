"""The bag tools' type store: the common types are rosbags' own Jazzy definitions, any other comes on demand."""
from __future__ import annotations

from rosbags.typesys import Stores, get_typestore

from cable_winch_monitor import channels
from cable_winch_monitor.bagio.decode import decode
from cable_winch_monitor.bagio.jazzy_types import FIELDDEFS
from cable_winch_monitor.bagio.reader import BagReader
from cable_winch_monitor.bagio.typestore import COMMON_TYPES, MSG_PACKAGE, knows, msg_dir, with_dependencies
from cable_winch_monitor.bagio.typestore import typestore as monitor_store
from cable_winch_monitor.bagio.writer import BagWriter
from cable_winch_monitor.messages import records


def test_common_types_are_rosbags_jazzy_definitions():
    """jazzy_types.py is rosbags' Jazzy store for the common types and all they use (else: run
    scripts/jazzy_types.py after a rosbags upgrade)."""
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    assert set(FIELDDEFS) == with_dependencies(jazzy, COMMON_TYPES)
    for name, definition in FIELDDEFS.items():
        assert definition == jazzy.fielddefs[name], f"{name} differs from rosbags' Jazzy store"


def test_every_type_the_monitor_reads_and_writes_is_in_the_store_it_starts_with():
    """No built-in input or output topic's type waits for rosbags' whole store (COMMON_TYPES lists them
    all; a user's channel may declare any other type)."""
    starting = set(FIELDDEFS) | {path.stem for path in msg_dir().glob("*.msg")}
    used = {*(channel.msgtype for channel in channels.BUILTIN), *records.OUTPUT_TYPES.values()}
    assert {name.rsplit("/", 1)[-1] if name.startswith(MSG_PACKAGE) else name for name in used} <= starting


def test_the_message_definitions_written_into_bags_are_jazzys():
    """A bag made with the common store carries the same schema text as one made with rosbags' whole store."""
    jazzy, store = get_typestore(Stores.ROS2_JAZZY), monitor_store()
    for name in COMMON_TYPES:
        assert store.generate_msgdef(name) == jazzy.generate_msgdef(name)


def test_another_jazzy_type_is_added_when_first_needed(tmp_path):
    """A topic of a type outside the common set (a shaft thermometer) is written, read and decoded."""
    temperature = "sensor_msgs/msg/Temperature"
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    message = jazzy.types[temperature](jazzy.types["std_msgs/msg/Header"](
        jazzy.types["builtin_interfaces/msg/Time"](12, 500), "shaft"), 18.25, 0.04)
    data = bytes(jazzy.serialize_cdr(message, temperature))
    with BagWriter(tmp_path / "bag") as writer:
        writer.write_raw("/shaft/temperature", temperature, 12_000_000_500, data)
    store = monitor_store()
    assert knows(store, temperature)
    (item,) = list(BagReader(tmp_path / "bag", {"/shaft/temperature": temperature}))
    assert (item.message.temperature, item.message.variance, item.message.header.frame_id) == (18.25, 0.04, "shaft")
    assert decode(data, temperature, store).header.stamp.nanosec == 500


def test_a_type_jazzy_does_not_define_stays_unknown():
    assert not knows(monitor_store(), "vendor_msgs/msg/RopeScan")
