"""The package's layers, bottom to top: a module or subpackage imports only from layers below its own.

Every top-level module and subpackage of cable_winch_monitor must be placed here, so that a
new one is placed on purpose; imports inside a subpackage are its own business, but for
`model`, whose parts by job have layers of their own (MODEL_LAYERS).
"""
from __future__ import annotations

import ast
from pathlib import Path

import cable_winch_monitor

PACKAGE = Path(cable_winch_monitor.__file__).parent
LAYERS = (  # bottom first
    {"paths", "progress", "seed002", "stopping", "safe_yaml", "frozen"},  # no package imports (files, progress bars, stop
                                        # signals, YAML read within bounds, fast frozen dataclasses)
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
    {"__main__"},                       # the console script's process around it
)
MODEL_LAYERS = (  # model's parts, bottom first
    {"plantfile", "conditions"},        # the plant file; a sample's operating conditions
    {"statics"},                        # poses, spans, the wrench balance, the load, the result type
    {"paper"},                          # seed 002's special cases and its traversal solver
    {"solvers"},                        # the energy solvers, one sample or many
    {"estimator"},                      # the estimator (its front door: model/estimator/__init__.py)
)




def _unit(path: Path) -> str:
    return path.relative_to(PACKAGE).parts[0].removesuffix(".py")


def _targets(path: Path) -> set[tuple[str, ...]]:
    """What the file `path` imports of the package, each as its dotted path below the package (relative
    imports resolved against the file's own package)."""
    package = path.relative_to(PACKAGE).parent.parts
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level > 0:
            base = package[:len(package) - (node.level - 1)]
            if node.module:
                out.add((*base, *node.module.split(".")))
            else:
                out.update((*base, alias.name) for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("cable_winch_monitor."):
            out.add(tuple(node.module.split(".")[1:]))
        elif isinstance(node, ast.Import):
            out.update(tuple(alias.name.split(".")[1:]) for alias in node.names
                       if alias.name.startswith("cable_winch_monitor."))
    return out


def _sources(below: Path = PACKAGE) -> list[Path]:
    return [p for p in below.rglob("*.py") if "__pycache__" not in p.parts and p != below / "__init__.py"]


def _downward(layers: tuple[set[str], ...], units: dict[Path, str], imported: dict[Path, set[str]]) -> list[str]:
    """The imports that do not point to a lower layer: each file's unit (`units`) against what it imports."""
    level = {unit: k for k, layer in enumerate(layers) for unit in layer}
    wrong = []
    for path, unit in units.items():
        for other in imported[path] - {unit}:
            if level.get(other, len(layers)) >= level[unit]:
                wrong.append(f"{path.relative_to(PACKAGE)} ({unit}, layer {level[unit]}) imports {other} "
                             f"(layer {level.get(other, '?')})")
    return wrong


def test_every_module_has_a_layer():
    placed = set().union(*LAYERS)
    assert {_unit(p) for p in _sources()} - placed == set()
    model = PACKAGE / "model"
    assert {p.relative_to(model).parts[0].removesuffix(".py") for p in _sources(model)} - set().union(*MODEL_LAYERS) \
        == set()


def test_imports_point_down():
    sources = _sources()
    units = {path: _unit(path) for path in sources}
    imported = {path: {target[0] for target in _targets(path)} for path in sources}
    assert not (wrong := _downward(LAYERS, units, imported)), "\n".join(wrong)


def test_the_models_parts_point_down():
    model = PACKAGE / "model"
    sources = _sources(model)
    units = {path: path.relative_to(model).parts[0].removesuffix(".py") for path in sources}
    imported = {path: {target[1] for target in _targets(path) if len(target) > 1 and target[0] == "model"}
                for path in sources}
    assert not (wrong := _downward(MODEL_LAYERS, units, imported)), "\n".join(wrong)
