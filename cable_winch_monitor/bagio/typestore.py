"""The ROS 2 Jazzy type store plus this package's messages, built from their .msg text.

Bag tools then need no compiled messages: rosbags serialises and deserialises from the
definitions, and writes the definitions into every bag it makes.
"""
from __future__ import annotations

import sys
from functools import lru_cache
from pathlib import Path

from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

MSG_PACKAGE = "cable_winch_monitor_msgs"


def msg_dir() -> Path:
    """`msg_defs/msg` of the source checkout, else the installed `share/cable_winch_monitor_msgs/msg`."""
    source = Path(__file__).resolve().parents[2] / "msg_defs" / "msg"
    if source.is_dir():
        return source
    return Path(sys.prefix) / "share" / MSG_PACKAGE / "msg"


@lru_cache(maxsize=1)
def typestore() -> Typestore:
    """Jazzy's standard types and cable_winch_monitor_msgs/msg/*, built once per process."""
    files = sorted(msg_dir().glob("*.msg"))
    if not files:
        raise FileNotFoundError(f"no {MSG_PACKAGE} message definitions in {msg_dir()}")
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for path in files:
        types.update(get_types_from_msg(path.read_text(), f"{MSG_PACKAGE}/msg/{path.stem}"))
    store.register(types)
    return store
