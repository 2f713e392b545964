"""Write cable_winch_monitor/bagio/jazzy_types.py: rosbags' ROS 2 Jazzy definitions of the message types
the monitor reads and writes, and of the types they use.

The bag tools start with these alone (building rosbags' whole Jazzy store imports every older
distribution's store: 55 ms at every start); other types are taken from the whole
store when a bag or a user's channel first needs one. Run this after upgrading rosbags if
test/bagio/test_typestore.py says the definitions differ:

    .venv/bin/python scripts/jazzy_types.py
"""
from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rosbags.interfaces import Nodetype  # noqa: E402 - after the path set-up above

from cable_winch_monitor.bagio.typestore import COMMON_TYPES, jazzy_store, with_dependencies  # noqa: E402

TARGET = ROOT / "cable_winch_monitor" / "bagio" / "jazzy_types.py"
HEADER = '''"""rosbags' ROS 2 Jazzy definitions (rosbags {version}) of the message types the monitor reads and writes.

Written by scripts/jazzy_types.py from rosbags' type store; test/bagio/test_typestore.py checks
that they are still rosbags' own. Do not edit: run the script again.
"""
from rosbags.interfaces import Nodetype as T

FIELDDEFS = {{
'''


def _node(value: object) -> str:
    """Python source of a field description, with rosbags' Nodetype by name."""
    if isinstance(value, tuple):
        return "(" + ", ".join(_node(item) for item in value) + ("," if len(value) == 1 else "") + ")"
    if isinstance(value, Nodetype):
        return f"T.{value.name}"
    return repr(value)


def source() -> str:
    from importlib.metadata import version
    store = jazzy_store()
    lines = [HEADER.format(version=version("rosbags"))]
    for name in sorted(with_dependencies(store, COMMON_TYPES)):
        consts, fields = store.fielddefs[name]
        lines.append(f"    {name!r}: (\n        {consts!r},\n        [\n")
        lines += [f"            ({field!r}, {_node(kind)}),\n" for field, kind in fields]
        lines.append("        ],\n    ),\n")
    lines.append("}\n")
    return "".join(lines)


if __name__ == "__main__":
    TARGET.write_text(source())
    print(f"wrote {TARGET}")
