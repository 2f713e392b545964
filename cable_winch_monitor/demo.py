"""Seed 002's four examples solved by both solvers, printed beside the paper's Table 2."""
from __future__ import annotations

import numpy as np

from . import seed002
from .model.plantfile.plant import Plant
from .model.solvers.solve import METHODS, solve
from .model.statics.result import Solution


def table2_values(solution: Solution) -> np.ndarray:
    """A solution in Table 2's row order: B1, B2, B3, C [m], tau_1..tau_4 [kN]."""
    assert solution.points_b is not None and solution.point_c is not None  # of a solved state
    assert solution.tensions is not None
    return np.concatenate([solution.points_b[:3].ravel(), solution.point_c, solution.tensions / 1e3])


def _ranges(solution: Solution) -> str:
    return " U ".join(f"[{lo:.3f}, {hi:.3f}]" for lo, hi in solution.rotation_range)


def run_demo(plant: Plant) -> int:
    """Print the comparison; exit status 1 if a solver disagrees with the physics-checked table."""
    mismatches = 0
    print(f"Seed 002 examples on plant '{plant.name}' (Table 1 lengths -> Table 2 pose and tensions)\n")
    for example, lengths in seed002.TABLE_1.items():
        solutions = {method: solve(plant, lengths, method=method) for method in METHODS}
        print(f"Example {example}: l = {lengths} m")
        for method, solution in solutions.items():
            print(f"  {method:<10} {solution.tension_state}")
        if example == 1:
            paper_phi = " U ".join(f"[{lo}, {hi}]" for lo, hi in seed002.EXAMPLE_1_RANGE)
            print(f"  {'paper':<10} single cable 1, phi = {paper_phi} rad")
            for method, solution in solutions.items():
                print(f"  {method:<10} phi = {_ranges(solution)} rad")
            print()
            continue
        print(f"  {'':<9}{'paper':>10}" + "".join(f"{m:>11}" for m in METHODS))
        values = {m: table2_values(s) if s.ok else np.full(16, np.nan) for m, s in solutions.items()}
        for row, name in enumerate(seed002.TABLE_2_ROWS):
            paper = seed002.TABLE_2[example][row]
            expected = seed002.physical_table2(example)[row]
            line = f"  {name:<9}{paper:>10.3f}" + "".join(f"{values[m][row]:>11.3f}" for m in METHODS)
            off = [m for m in METHODS if not abs(values[m][row] - expected) <= seed002.TABLE_2_TOLERANCE]
            if expected != paper:
                line += f"   misprint: equilibrium needs {expected:.3f}"
            if off:
                line += "   <- differs: " + ", ".join(off)
                mismatches += 1
            print(line)
        print()
    print("all entries agree with Table 2 to its printed precision (one misprint noted)" if not mismatches
          else f"{mismatches} entries differ from Table 2")
    return 0 if not mismatches else 1
