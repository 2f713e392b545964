"""The package's layers, bottom to top: a module or subpackage imports only from layers below its own.

Every top-level module and subpackage of cable_winch_monitor must be placed here, so that a
new one is placed on purpose; imports inside a subpackage are its own business.
"""
from __future__ import annotations

import ast
from pathlib import Path

import cable_winch_monitor

PACKAGE = Path(cable_winch_monitor.__file__).parent
LAYERS = (  # bottom first
    {"paths", "progress", "seed002", "stopping", "safe_yaml"},  # no package imports (files, progress bars, stop
                                        # signals, YAML read within bounds)
    {"bagio"},                          # bag files: MCAP/rosbag2, CDR, type store, salvage (a bag's YAML bounded)
    {"model"},                          # plant file, mechanics, solvers, estimation
    {"channels", "formatting", "demo"},  # what a sensor channel is; printing solutions; the paper's examples
    {"effects"},                        # physical effects and the plant model they make
    {"monitor"},                        # a sample's estimate, clearance, alarm, diagnostics
    {"messages", "live"},               # the monitor's messages and records; the live scheduler
    {"sim", "nodes", "replay", "analysis"},  # the simulator; the ROS 2 nodes; replay of a bag; model vs measurement
    {"fleet"},                          # many bags
    {"bench"},                          # benchmarks
    {"cli"},                            # the command line
)


def _unit(path: Path) -> str:
    return path.relative_to(PACKAGE).parts[0].removesuffix(".py")


def _imported(path: Path) -> set[str]:
    """The package's top-level modules or subpackages that the file `path` imports."""
    inside = path.parent != PACKAGE
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level > 0:
            if inside and node.level == 1:
                continue  # its own subpackage
            if node.module:
                out.add(node.module.split(".")[0])
            else:
                out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("cable_winch_monitor."):
            out.add(node.module.split(".")[1])
        elif isinstance(node, ast.Import):
            out.update(alias.name.split(".")[1] for alias in node.names if alias.name.startswith("cable_winch_monitor."))
    return out


def _sources() -> list[Path]:
    return [p for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts and p != PACKAGE / "__init__.py"]


def test_every_module_has_a_layer():
    placed = set().union(*LAYERS)
    assert {_unit(p) for p in _sources()} - placed == set()


def test_imports_point_down():
    level = {unit: k for k, layer in enumerate(LAYERS) for unit in layer}
    wrong = []
    for path in _sources():
        unit = _unit(path)
        for imported in _imported(path) - {unit}:
            if level.get(imported, len(LAYERS)) >= level[unit]:
                wrong.append(f"{path.relative_to(PACKAGE)} ({unit}, layer {level[unit]}) imports {imported} "
                             f"(layer {level.get(imported, '?')})")
    assert not wrong, "\n".join(wrong)
