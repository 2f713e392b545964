"""One result type for every solve, and the physics checks every solution must pass."""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from enum import Enum
from functools import lru_cache
from typing import Any, Generic, TypeVar

import numpy as np

from ...frozen import fast_init
from ..plantfile.plant import CABLE_NAMES, Plant
from .geometry import attachment_points, quaternion_from_rotation, roll_pitch_yaw, wrench_residuals


class SolveStatus(str, Enum):
    """How a solve ended. The values are stable identifiers used in JSON and messages."""

    SOLVED = "solved"
    SINGLE_CABLE_INDETERMINATE = "single_cable_indeterminate"
    NO_EQUILIBRIUM = "no_equilibrium"
    INVALID_INPUT = "invalid_input"
    SOLVER_FAILED = "solver_failed"


T = TypeVar("T")


class computed_once(Generic[T]):
    """A property worked out at its first use and kept on the instance: functools.cached_property
    without the lock Python 3.11 takes at every first use (0.5 -> 0.2 us; a replay asks a few of
    these of every solved sample)."""

    def __init__(self, function: Callable[[Any], T]):
        self.function, self.name = function, function.__name__
        self.__doc__ = function.__doc__

    def __get__(self, instance: Any, owner: type | None = None) -> T:
        if instance is None:
            return self  # type: ignore[return-value]
        value = instance.__dict__[self.name] = self.function(instance)
        return value


@fast_init
@dataclass(frozen=True)
class Solution:
    """Static equilibrium of the platform for four cable lengths.

    Arrays are in `shaft` and SI units. Pose fields are None unless status is SOLVED;
    for a single-cable state `single_cable` (0-based) and `rotation_range` (the set phi of
    seed 002, 3.1, as [start, end] intervals in [0, 2 pi]) say what is known instead.
    """

    status: SolveStatus
    message: str
    method: str
    lengths: np.ndarray
    taut: np.ndarray | None = None
    tensions: np.ndarray | None = None
    rotation: np.ndarray | None = None
    position: np.ndarray | None = None
    points_b: np.ndarray | None = None
    point_c: np.ndarray | None = None
    spans: np.ndarray | None = None
    force_residual: float = float("nan")
    moment_residual: float = float("nan")
    iterations: int = 0
    single_cable: int | None = None
    rotation_range: tuple[tuple[float, float], ...] = ()
    load: np.ndarray | None = None  # the external wrench solved for (model.load); None: gravity
    extras: dict[str, Any] = field(default_factory=dict)

    @computed_once
    def ok(self) -> bool:
        """Solved: a pose (asked a dozen times of each sample's solution on its way through replay)."""
        return self.status is SolveStatus.SOLVED

    @computed_once
    def taut_set(self) -> tuple[int, ...]:
        """1-based numbers of the taut cables, as the paper writes them."""
        if self.taut is None:
            return ()
        return _taut_set(np.asarray(self.taut, dtype=bool).tobytes())

    @computed_once
    def tension_state(self) -> str:
        """Plain words: 'taut {1,2,4}', 'single cable 1: pose indeterminate', ..."""
        if self.status is SolveStatus.SOLVED:
            return _taut_words(self.taut_set)
        if self.status is SolveStatus.SINGLE_CABLE_INDETERMINATE:
            assert self.single_cable is not None  # a single-cable solution names its cable
            return f"single cable {self.single_cable + 1}: pose indeterminate"
        return self.status.value.replace("_", " ")

    @property
    def failure(self) -> str:
        """Why there is no pose, in one line ('' when solved): the tension state, and what is wrong with an
        invalid input (a bad length, an effect's hook that failed)."""
        if self.ok:
            return ""
        if self.status is SolveStatus.INVALID_INPUT and self.message:
            return f"{self.tension_state}: {self.message}"
        return self.tension_state

    @computed_once
    def quaternion(self) -> np.ndarray | None:
        return None if self.rotation is None else quaternion_from_rotation(self.rotation)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready content: tensions in N, points in m, angles in rad."""
        def listed(array: np.ndarray | None) -> Any:
            return None if array is None else np.round(np.asarray(array, dtype=float), 9).tolist()

        out: dict[str, Any] = {
            "status": self.status.value,
            "message": self.message,
            "method": self.method,
            "tension_state": self.tension_state,
            "lengths": listed(self.lengths),
            "taut": None if self.taut is None else [bool(t) for t in self.taut],
            "tensions": listed(self.tensions),
            "B": listed(self.points_b),
            "C": listed(self.point_c),
            "position": listed(self.position),
            "quaternion_xyzw": listed(self.quaternion),
            "spans": listed(self.spans),
            "force_residual": self.force_residual,
            "moment_residual": self.moment_residual,
            "iterations": self.iterations,
        }
        if self.rotation is not None:
            out["roll_pitch_yaw"] = list(roll_pitch_yaw(self.rotation))
        if self.single_cable is not None:
            out["single_cable"] = CABLE_NAMES[self.single_cable]
            out["rotation_range"] = [list(interval) for interval in self.rotation_range]
        return out


@lru_cache(maxsize=64)
def _taut_set(taut: bytes) -> tuple[int, ...]:
    """`Solution.taut_set` of a taut mask's bytes (a few masks, asked of every solution)."""
    return tuple(i + 1 for i, flag in enumerate(taut) if flag)


@lru_cache(maxsize=64)
def _taut_words(taut_set: tuple[int, ...]) -> str:
    return "taut {" + ",".join(str(i) for i in taut_set) + "}"


def failed(status: SolveStatus, message: str, method: str, lengths: Sequence[float] | np.ndarray, **kwargs: Any) -> Solution:
    """A Solution without a pose."""
    return Solution(status=status, message=message, method=method, lengths=np.asarray(lengths, dtype=float), **kwargs)


def validate_lengths(lengths: Any, max_length: float = np.inf) -> tuple[np.ndarray | None, str]:
    """Four finite positive lengths no longer than `max_length` as an array, or None and the reason they are not.

    Strings are refused even where numpy would parse them: a length is a number.
    """
    if lengths is None:
        return None, "cable lengths missing: need exactly 4 numbers, got None"
    items = lengths if isinstance(lengths, (list, tuple)) else [lengths]
    if any(isinstance(item, (str, bytes)) for item in items):
        return None, f"cable lengths must be numbers, got {lengths!r}"
    try:
        array = np.asarray(lengths, dtype=float)
    except (TypeError, ValueError):
        return None, f"cable lengths must be numbers, got {lengths!r}"
    if array.shape != (4,):
        return None, f"need exactly 4 cable lengths, got {array.size}"
    bad = [f"{CABLE_NAMES[i]}={array[i]}" for i in range(4) if not np.isfinite(array[i])]
    if bad:
        return None, "cable lengths must be finite: " + ", ".join(bad)
    bad = [f"{CABLE_NAMES[i]}={array[i]}" for i in range(4) if array[i] <= 0.0]
    if bad:
        return None, "cable lengths must be positive: " + ", ".join(bad)
    bad = [f"{CABLE_NAMES[i]}={array[i]:.6g}" for i in range(4) if array[i] > max_length]
    if bad:
        return None, f"cable lengths beyond the maximum payout {max_length:g} m: " + ", ".join(bad)
    return array, ""


def single_cable_result(plant: Plant, method: str, lengths: np.ndarray, cable: int,
                        intervals: tuple[tuple[float, float], ...], extras: dict[str, Any],
                        load: np.ndarray | None = None) -> Solution:
    """The platform hangs from `cable` alone: that rope carries the load's force (A, B and C on a
    plumb line), the others are slack, and the pose is known only up to a turn within `intervals`."""
    load = plant.wrench if load is None else load
    ranges = " U ".join(f"[{lo:.3f}, {hi:.3f}]" for lo, hi in intervals)
    return failed(SolveStatus.SINGLE_CABLE_INDETERMINATE,
                  f"platform hangs from {CABLE_NAMES[cable]} alone: pose indeterminate, it can turn through "
                  f"{ranges} rad about the cable", method, lengths, taut=np.arange(4) == cable,
                  tensions=np.where(np.arange(4) == cable, float(np.linalg.norm(load[:3])), 0.0), single_cable=cable,
                  rotation_range=intervals, load=load, extras=extras)


def guarded_solve(method: str, lengths: Any, solve_valid: Callable[[np.ndarray], Solution],
                  load_problem: str = "", plant: Plant | None = None) -> Solution:
    """Validate the lengths (and take `load_problem`, why the load is unusable, as invalid input),
    then solve; a bad input or a numerical failure becomes a status.

    The contract of every solver: whatever the input, a Solution comes back, never an
    exception (a live monitor must report and go on). The rigid solvers pass their
    `plant`: lengths beyond its maximum payout are refused and a solved result must pass
    the physics check (`physics_guard`).
    """
    array, reason = validate_lengths(lengths, np.inf if plant is None else plant.max_payout)
    if array is None or load_problem:
        return failed(SolveStatus.INVALID_INPUT, reason or load_problem, method,
                      np.full(4, np.nan) if array is None else array)
    try:
        with np.errstate(all="ignore"):
            solution = solve_valid(array)
            return solution if plant is None else physics_guard(plant, solution)
    except Exception as error:
        return failed(SolveStatus.SOLVER_FAILED, f"{method} solver failed: {type(error).__name__}: {error}",
                      method, array)


def physics_guard(plant: Plant, solution: Solution) -> Solution:
    """`solution` if it is not SOLVED or passes `check_physics`; else SOLVER_FAILED with what failed.

    Nothing reaches the monitor as solved that does not balance: a solver that converged
    to nonsense (huge lengths, lost precision) is a failure, said as one.
    """
    if not solution.ok:
        return solution
    reason = check_physics(plant, solution).failure()
    if not reason:
        return solution
    return failed(SolveStatus.SOLVER_FAILED, f"{solution.method} solver: result fails the physics check ({reason})",
                  solution.method, solution.lengths, iterations=solution.iterations,
                  force_residual=solution.force_residual, moment_residual=solution.moment_residual)


def solved(plant: Plant, method: str, lengths: np.ndarray, rotation: np.ndarray, position: np.ndarray,
           tensions: np.ndarray, taut: np.ndarray, iterations: int, message: str = "static equilibrium found",
           load: np.ndarray | None = None, **extras: Any) -> Solution:
    """A SOLVED Solution with its points, spans and equilibrium residuals (under `load`; None: gravity)."""
    loads = None if load is None else np.asarray(load, dtype=float)[None]
    return solved_rows(plant, method, lengths[None], rotation[None], position[None], np.asarray(tensions)[None],
                       np.asarray(taut)[None], [iterations], message, extras, loads)[0]


def solved_rows(plant: Plant, method: str, lengths: np.ndarray, rotation: np.ndarray, position: np.ndarray,
                tensions: np.ndarray, taut: np.ndarray, iterations: Sequence[int],
                message: str = "static equilibrium found", extras: dict[str, Any] | None = None,
                loads: np.ndarray | None = None, anchors: np.ndarray | None = None) -> list[Solution]:
    """`solved` for N stacked samples (lengths (N, 4), rotation (N, 3, 3), loads (N, 6) or None for
    gravity, anchors (N, 4, 3) where the geometry depends on the pose, else None for the plant's, ...):
    the points, spans and residuals of all rows are computed together."""
    points_b, point_c = attachment_points(plant, rotation, position)
    loads = np.broadcast_to(plant.wrench, (len(lengths), 6)) if loads is None else loads
    geometry = plant if anchors is None else plant.with_changes(anchors=anchors)  # stacked anchors broadcast
    force, moment = wrench_residuals(geometry, points_b, point_c, tensions, loads)
    spans = np.linalg.norm(points_b - geometry.anchors, axis=-1)
    taut, tensions = np.asarray(taut, dtype=bool), np.asarray(tensions, dtype=float)
    rows = zip(lengths, taut, tensions, rotation, position, points_b, point_c, spans, force.tolist(), moment.tolist(),
               np.asarray(iterations).tolist(), loads)
    return [Solution(SolveStatus.SOLVED, message, method, length, flags, pulls, turn, place, points, point, span,
                     force_residual, moment_residual, count, load=load, extras=dict(extras or {}))
            for length, flags, pulls, turn, place, points, point, span, force_residual, moment_residual, count, load
            in rows]


FloatRows = float | np.ndarray  # one state's value, or one per row
BoolRows = bool | np.ndarray


@dataclass(frozen=True)
class PhysicsCheck:
    """What a solved state must satisfy: balance, tensions >= 0, slack spans within their lengths.
    Each field is a number for one state, or an (N,) array from `check_physics_rows`."""

    force_residual: FloatRows
    moment_residual: FloatRows
    min_tension: FloatRows
    max_overstretch: FloatRows  # max(span - length) over all cables [m]
    taut_length_error: FloatRows  # max |span - length| over taut cables [m]
    rigid_error: FloatRows  # max deviation of the solved points from the rigid body [m]
    slack_tension: FloatRows  # max |tension| over slack cables [N]
    mirrored: BoolRows  # solved points are the mirror image of the body

    def passes(self, balance_tol: float = 1e-6, length_tol: float = 1e-6) -> bool:
        return bool(passing_rows(self, balance_tol, length_tol))

    def failure(self, balance_tol: float = 1e-6, length_tol: float = 1e-6) -> str:
        """What fails, in words ('' if the check passes; NaN fails every comparison)."""
        problems = [
            (self.force_residual <= balance_tol, f"force residual {self.force_residual:.3g} mg"),
            (self.moment_residual <= balance_tol, f"moment residual {self.moment_residual:.3g}"),
            (self.min_tension >= 0.0, f"negative tension {self.min_tension:.6g} N"),
            (self.max_overstretch <= length_tol, f"a span exceeds its length by {self.max_overstretch:.3g} m"),
            (self.taut_length_error <= length_tol, f"a taut span misses its length by {self.taut_length_error:.3g} m"),
            (self.rigid_error <= length_tol, f"body deformed by {self.rigid_error:.3g} m"),
            (self.slack_tension == 0.0, f"slack cable carries {self.slack_tension:.6g} N"),
            (not self.mirrored, "mirror image of the body"),
        ]
        return "; ".join(text for ok, text in problems if not ok)


def check_physics(plant: Plant, solution: Solution) -> PhysicsCheck:
    """Recompute the physics of a SOLVED solution from its points, independently of the solver."""
    if solution.status is not SolveStatus.SOLVED:
        raise ValueError(f"no pose to check: {solution.tension_state}")
    assert solution.points_b is not None and solution.point_c is not None  # a SOLVED solution has its points
    rows = check_physics_rows(plant, solution.lengths[None], solution.points_b[None], solution.point_c[None],
                              np.asarray(solution.tensions)[None], np.asarray(solution.taut)[None],
                              None if solution.load is None else np.asarray(solution.load)[None])
    return PhysicsCheck(**{name: getattr(rows, name)[0].item() for name in PhysicsCheck.__dataclass_fields__})


def check_physics_rows(plant: Plant, lengths: np.ndarray, points_b: np.ndarray, point_c: np.ndarray,
                       tensions: np.ndarray, taut: np.ndarray, loads: np.ndarray | None = None) -> PhysicsCheck:
    """`check_physics` of N stacked solved states (lengths (N, 4), points_b (N, 4, 3), loads (N, 6) or None
    for gravity, ...): a PhysicsCheck whose fields are (N,) arrays; `passing_rows` says which rows pass."""
    force, moment = wrench_residuals(plant, points_b, point_c, tensions, loads)
    excess = np.linalg.norm(points_b - plant.anchors, axis=-1) - lengths
    body = np.vstack([plant.attachments, plant.cog])
    world = np.concatenate([points_b, point_c[:, None, :]], axis=1)
    body_distances = np.linalg.norm(body[:, None] - body[None], axis=-1)
    world_distances = np.linalg.norm(world[:, :, None] - world[:, None], axis=-1)

    def handedness(points: np.ndarray) -> np.ndarray:
        """Signed volume of B1, B2, B3, C: changes sign under a mirror image."""
        return np.linalg.det(points[..., [1, 2, 4], :] - points[..., :1, :])

    return PhysicsCheck(
        force_residual=force,
        moment_residual=moment,
        min_tension=tensions.min(axis=1),
        max_overstretch=excess.max(axis=1),
        taut_length_error=np.where(taut, np.abs(excess), 0.0).max(axis=1),
        rigid_error=np.abs(world_distances - body_distances).max(axis=(1, 2)),
        slack_tension=np.where(taut, 0.0, np.abs(tensions)).max(axis=1),
        mirrored=handedness(world) * handedness(body) < 0.0,
    )


def passing_rows(check: PhysicsCheck, balance_tol: float = 1e-6, length_tol: float = 1e-6) -> np.ndarray | np.bool_:
    """Which rows of a `check_physics_rows` check pass (the conditions of `PhysicsCheck.passes`); for a
    one-state check, whether it passes."""
    return ((check.force_residual <= balance_tol) & (check.moment_residual <= balance_tol)
            & (check.min_tension >= 0.0) & (check.max_overstretch <= length_tol)
            & (check.taut_length_error <= length_tol) & (check.rigid_error <= length_tol)
            & (check.slack_tension == 0.0) & np.logical_not(check.mirrored))
