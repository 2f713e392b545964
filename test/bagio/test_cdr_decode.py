"""The compiled CDR decoders give what rosbags gives, for good bytes and for damaged ones."""
from __future__ import annotations

import random

import numpy as np
import pytest

from cable_winch_monitor.bagio.decode import decode, decoder
from cable_winch_monitor.bagio.mcapfile import McapFile
from cable_winch_monitor.bagio.typestore import typestore
from cable_winch_monitor.paths import demo_bag
from cable_winch_monitor.replay import replay


def same(got, want, path="msg"):
    """Equal message objects: same classes, numbers (NaN equal to NaN), strings and array dtypes."""
    if hasattr(want, "__dataclass_fields__"):
        assert type(got) is type(want), path
        for name in want.__dataclass_fields__:
            same(getattr(got, name), getattr(want, name), f"{path}.{name}")
    elif isinstance(want, np.ndarray):
        assert isinstance(got, np.ndarray) and got.dtype == want.dtype, path
        assert np.array_equal(got, want, equal_nan=True), path
    elif isinstance(want, list):
        assert isinstance(got, list) and len(got) == len(want), path
        for k, (g, w) in enumerate(zip(got, want)):
            same(g, w, f"{path}[{k}]")
    else:
        assert type(got) is type(want) and (got == want or got != got and want != want), (path, got, want)


@pytest.fixture(scope="module")
def raw_messages(tmp_path_factory):
    """Every message of the demo bag and of its replay (inputs and every output type) as (type, bytes)."""
    out = tmp_path_factory.mktemp("decode") / "replayed"
    replay(demo_bag(), out, progress=False)
    found = []
    with McapFile(next(out.glob("*.mcap"))) as mcap:
        for raw in mcap.messages():
            channel = mcap.channels[raw.channel_id]
            found.append((mcap.schemas[channel.schema_id].name, raw.data))
    return found


def test_every_message_decodes_as_rosbags_decodes_it(raw_messages):
    store = typestore()
    types = {msgtype for msgtype, _ in raw_messages}
    assert len(types) == 11, types  # the inputs, the package's outputs, TFMessage, MarkerArray, DiagnosticArray
    byte_fields = {"diagnostic_msgs/msg/DiagnosticArray"}  # DiagnosticStatus.level is a byte: rosbags decodes it
    assert all((decoder(msgtype, store) is None) == (msgtype in byte_fields) for msgtype in types)
    for msgtype, data in raw_messages:
        same(decode(data, msgtype, store), store.deserialize_cdr(data, msgtype))


def test_damaged_bytes_fail_where_rosbags_fails_and_decode_alike_elsewhere(raw_messages):
    store = typestore()
    rng = random.Random(2)
    outcomes = {"both fail": 0, "both decode": 0}
    for msgtype, data in rng.sample(raw_messages, 2000):
        damaged = bytearray(data)
        cut, flip, extra = rng.random() < 0.3, rng.random() < 0.5, rng.random() < 0.3
        if cut:
            damaged = damaged[:rng.randrange(1, len(damaged))]
        if flip and len(damaged) > 5:
            damaged[rng.randrange(4, len(damaged))] = rng.randrange(256)
        if extra:
            damaged += bytes(rng.randrange(1, 9))
        damaged = bytes(damaged)
        try:
            want = store.deserialize_cdr(damaged, msgtype)
        except Exception:
            with pytest.raises(Exception):  # noqa: B017 - whatever rosbags raised, decode must fail too
                decode(damaged, msgtype, store)
            outcomes["both fail"] += 1
        else:
            same(decode(damaged, msgtype, store), want)
            outcomes["both decode"] += 1
    assert outcomes["both fail"] > 300 and outcomes["both decode"] > 100


def test_big_endian_goes_to_rosbags():
    store = typestore()
    message = store.types["geometry_msgs/msg/Point"](x=1.5, y=-2.0, z=3.25)
    big = store.serialize_cdr(message, "geometry_msgs/msg/Point", little_endian=False)
    assert big[:2] == b"\x00\x00"
    same(decode(big, "geometry_msgs/msg/Point", store), message)
