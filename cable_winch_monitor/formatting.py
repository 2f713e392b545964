"""Plain-text views of solutions for the command line."""
from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from .model.plantfile.plant import CABLE_NAMES
from .model.statics.geometry import roll_pitch_yaw
from .model.statics.result import Solution


def _row(label: str, values: Iterable[Any], fmt: str = "{:>10.3f}") -> str:
    return f"{label:<22}" + "".join(fmt.format(v) for v in values)


def format_solution(solution: Solution) -> str:
    """The tension state, taut cables, tensions [kN], B1..B4, C, residual; phi for one cable."""
    lines = [_row("cable", CABLE_NAMES, "{:>10}"), _row("length l_i [m]", solution.lengths)]
    lines.append(f"{'tension state':<22}{solution.tension_state}   ({solution.status.value}, {solution.method} solver, "
                 f"{solution.iterations} iterations)")
    if solution.ok:
        assert solution.taut is not None and solution.tensions is not None and solution.spans is not None  # solved
        assert solution.points_b is not None and solution.point_c is not None and solution.rotation is not None
        lines += [
            _row("taut", ["yes" if t else "slack" for t in solution.taut], "{:>10}"),
            _row("tension [kN]", solution.tensions / 1e3),
            _row("span |A_iB_i| [m]", solution.spans),
        ]
        for axis, name in enumerate("xyz"):
            lines.append(_row(f"B_i {name} [m]", solution.points_b[:, axis]))
        c = solution.point_c
        roll, pitch, yaw = np.degrees(roll_pitch_yaw(solution.rotation))
        lines += [
            f"{'C [m]':<22}({c[0]:.3f}, {c[1]:.3f}, {c[2]:.3f})",
            f"{'roll/pitch/yaw [deg]':<22}{roll:.3f} / {pitch:.3f} / {yaw:.3f}",
            f"{'equilibrium residual':<22}force {solution.force_residual:.1e} mg, "
            f"moment {solution.moment_residual:.1e} mg*max|CB_i|",
        ]
    elif solution.single_cable is not None:
        ranges = " U ".join(f"[{lo:.3f}, {hi:.3f}]" for lo, hi in solution.rotation_range)
        lines.append(f"{'rotation range phi':<22}{ranges} rad about {CABLE_NAMES[solution.single_cable]}")
    else:
        lines.append(f"{'':<22}{solution.message}")
    return "\n".join(lines)
