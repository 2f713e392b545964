"""The type store of the bag tools: ROS 2 Jazzy's types and cable_winch_monitor_msgs, from their definitions.

Bag tools then need no compiled messages: rosbags serialises and deserialises from the
definitions, and writes the definitions into every bag it makes.

The store starts with the types the monitor reads and writes (`COMMON_TYPES`, in rosbags'
own Jazzy definitions, kept in jazzy_types.py) and this package's messages: building
rosbags' whole Jazzy store imports every older distribution's store (55 ms at every start,
against 15 ms for this one). `knows` adds any other Jazzy type (a user's channel, a vendor topic in
`compare`'s bag fields) from the whole store the first time it is asked for.
"""
from __future__ import annotations

import sys
from collections.abc import Iterable
from functools import lru_cache
from pathlib import Path
from typing import Any, cast

from rosbags.interfaces import Nodetype
from rosbags.interfaces.typing import Typesdict
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

MSG_PACKAGE = "cable_winch_monitor_msgs"
# What the monitor reads (the winches, inclinometer, depth gauge) and writes besides its own messages.
COMMON_TYPES = ("sensor_msgs/msg/JointState", "sensor_msgs/msg/Imu", "geometry_msgs/msg/PointStamped",
                "geometry_msgs/msg/PoseStamped", "tf2_msgs/msg/TFMessage", "visualization_msgs/msg/MarkerArray",
                "diagnostic_msgs/msg/DiagnosticArray")


def msg_dir() -> Path:
    """`msg_defs/msg` of the source checkout, else the installed `share/cable_winch_monitor_msgs/msg`."""
    source = Path(__file__).resolve().parents[2] / "msg_defs" / "msg"
    if source.is_dir():
        return source
    return Path(sys.prefix) / "share" / MSG_PACKAGE / "msg"


@lru_cache(maxsize=1)
def typestore() -> Typestore:
    """The common Jazzy types and cable_winch_monitor_msgs/msg/*, built once per process."""
    from .jazzy_types import FIELDDEFS  # written by scripts/jazzy_types.py

    files = sorted(msg_dir().glob("*.msg"))
    if not files:
        raise FileNotFoundError(f"no {MSG_PACKAGE} message definitions in {msg_dir()}")
    store = get_typestore(Stores.EMPTY)
    types = cast(Typesdict, dict(FIELDDEFS))  # rosbags' own definitions; mypy infers only the literal's outline
    for path in files:
        types.update(get_types_from_msg(path.read_text(), f"{MSG_PACKAGE}/msg/{path.stem}"))
    store.register(types)
    return store


@lru_cache(maxsize=1)
def jazzy_store() -> Typestore:
    """rosbags' whole ROS 2 Jazzy store (built on first use)."""
    return get_typestore(Stores.ROS2_JAZZY)


def knows(store: Typestore, msgtype: str) -> bool:
    """Whether `store` has `msgtype`, once it is added, with the types it uses, from rosbags' Jazzy
    store if that defines it."""
    if msgtype in store.types:
        return True
    jazzy = jazzy_store()
    if msgtype not in jazzy.fielddefs:
        return False
    store.register({name: jazzy.fielddefs[name] for name in with_dependencies(jazzy, [msgtype])
                    if name not in store.types})
    return True


def with_dependencies(store: Typestore, msgtypes: Iterable[str]) -> set[str]:
    """`msgtypes` and every message type their fields use, at any depth."""
    found: set[str] = set()
    pending = list(msgtypes)
    node: Nodetype
    argument: Any  # as `node` says: a base type, a message type's name, or an array's (element, length)
    while pending:
        name = pending.pop()
        if name in found:
            continue
        found.add(name)
        for _, (node, argument) in store.fielddefs[name][1]:
            if node in (Nodetype.ARRAY, Nodetype.SEQUENCE):
                node, argument = argument[0]
            if node == Nodetype.NAME:
                pending.append(argument)
    return found
