"""Pose conversions and the stacked (many-sample) forms of the per-sample geometry."""
import numpy as np
import pytest
from lengths import random_lengths

from cable_winch_monitor.model.plantfile.plant import load_plant
from cable_winch_monitor.model.solvers.batched import solve_batch
from cable_winch_monitor.model.statics.geometry import (
    quaternion_from_rotation,
    quaternions_from_rotations,
    roll_pitch_of_quaternion,
    roll_pitch_yaw,
    rotation_from_vector,
    structure_matrix,
    wrench_residual,
    wrench_residuals,
)
from cable_winch_monitor.model.statics.result import solved, solved_rows
from cable_winch_monitor.monitor.clearance import (
    batch_clearances,
    clearance_at_pose,
    clearances_at_poses,
    solution_clearances,
)

RNG = np.random.default_rng(7)
ROTATIONS = [rotation_from_vector(RNG.normal(size=3) * RNG.uniform(0.0, 3.0)) for _ in range(200)]


def rotate_by_quaternion(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """v turned by the unit quaternion q = (x, y, z, w): q v q*."""
    u, w = q[:3], q[3]
    return v + 2.0 * np.cross(u, np.cross(u, v) + w * v)


@pytest.mark.parametrize("index", range(0, 200, 7))
def test_quaternion_turns_vectors_as_its_matrix(index):
    rotation = ROTATIONS[index]
    q = quaternion_from_rotation(rotation)
    assert abs(np.linalg.norm(q) - 1.0) < 1e-12 and q[3] >= 0.0
    for v in np.eye(3):
        assert np.allclose(rotate_by_quaternion(q, v), rotation @ v, atol=1e-12)


def test_stacked_quaternions_take_every_branch_of_shepperds_method():
    """A stack with rotations of near a half turn about each axis (each diagonal element the largest in turn,
    the trace negative) and of small angles (the trace positive): each quaternion turns vectors as its
    matrix, is a unit one with w >= 0, and is the one its rotation gives alone."""
    axes = [*np.eye(3), *(RNG.normal(size=(30, 3)))]
    rotations = np.array([rotation_from_vector(axis / np.linalg.norm(axis) * angle)
                          for axis in axes for angle in (1e-6, 0.3, np.pi - 1e-3, np.pi)])
    diagonal = np.diagonal(rotations, axis1=1, axis2=2)
    assert (diagonal.sum(axis=1) > 0).any() and set(np.argmax(diagonal[diagonal.sum(axis=1) <= 0], axis=1)) == {0, 1, 2}
    stacked = quaternions_from_rotations(rotations)
    for rotation, q in zip(rotations, stacked):
        assert abs(np.linalg.norm(q) - 1.0) < 1e-12 and q[3] >= 0.0
        for v in np.eye(3):
            assert np.allclose(rotate_by_quaternion(q, v), rotation @ v, atol=1e-12)
        assert np.array_equal(q, quaternion_from_rotation(rotation))


def test_roll_pitch_of_a_quaternion_match_those_of_its_matrix_even_unnormalised():
    for rotation in ROTATIONS:
        roll, pitch, _ = roll_pitch_yaw(rotation)
        scale = RNG.uniform(0.5, 2.0)
        assert np.allclose(roll_pitch_of_quaternion(scale * quaternion_from_rotation(rotation)), (roll, pitch),
                           atol=1e-12)


def test_roll_pitch_yaw_rebuild_the_rotation_rep103_fixed_axes():
    for rotation in ROTATIONS:
        roll, pitch, yaw = roll_pitch_yaw(rotation)
        rebuilt = (rotation_from_vector(np.array([0.0, 0.0, yaw])) @ rotation_from_vector(np.array([0.0, pitch, 0.0]))
                   @ rotation_from_vector(np.array([roll, 0.0, 0.0])))
        assert np.allclose(rebuilt, rotation, atol=1e-9)


def stacked_poses(count: int) -> tuple[np.ndarray, np.ndarray]:
    tilts = [rotation_from_vector(RNG.normal(size=3) * 0.05) for _ in range(count)]
    positions = np.column_stack([RNG.normal(size=(count, 2)) * 0.3, RNG.uniform(-500.0, -5.0, count)])
    return np.array(tilts), positions


def test_stacked_structure_matrix_and_residuals_equal_the_per_sample_ones():
    plant = load_plant()
    rotations, positions = stacked_poses(50)
    points_b = positions[:, None, :] + plant.attachments @ np.swapaxes(rotations, -1, -2)
    point_c = positions + rotations @ plant.cog
    tensions = RNG.uniform(0.0, plant.weight, size=(50, 4))
    force, moment = wrench_residuals(plant, points_b, point_c, tensions)
    stacked = structure_matrix(plant, points_b, point_c)
    for i in range(50):
        assert np.allclose(stacked[i], structure_matrix(plant, points_b[i], point_c[i]), rtol=0.0, atol=1e-15)
        assert np.allclose((force[i], moment[i]), wrench_residual(plant, points_b[i], point_c[i], tensions[i]),
                           rtol=1e-14, atol=0.0)


def test_solved_rows_equal_solved_one_at_a_time():
    plant = load_plant()
    rotations, positions = stacked_poses(20)
    lengths = RNG.uniform(5.0, 500.0, size=(20, 4))
    tensions = RNG.uniform(0.0, plant.weight, size=(20, 4))
    taut = tensions > 0.3 * plant.weight
    rows = solved_rows(plant, "energy", lengths, rotations, positions, tensions, taut, list(range(20)))
    for i, row in enumerate(rows):
        single = solved(plant, "energy", lengths[i], rotations[i], positions[i], tensions[i], taut[i], i)
        for name in ("points_b", "point_c", "spans", "tensions", "lengths"):
            assert np.allclose(getattr(row, name), getattr(single, name), rtol=0.0, atol=1e-12), name
        assert (row.taut_set, row.iterations) == (single.taut_set, i)
        assert np.isclose(row.force_residual, single.force_residual, rtol=1e-14, atol=0.0)


def test_clearances_together_equal_clearance_pose_by_pose():
    plant = load_plant()
    rotations, positions = stacked_poses(30)
    together = clearances_at_poses(plant, rotations, positions)
    for rotation, position, clearance in zip(rotations, positions, together):
        single = clearance_at_pose(plant, rotation, position)
        assert (clearance.point_name, clearance.value) == (single.point_name, pytest.approx(single.value, abs=1e-12))
        # the reported point is on the outline, and its horizontal distance to the wall is the clearance
        assert np.allclose(position + rotation @ clearance.point_platform, clearance.point_shaft, atol=1e-12)
        radius = np.hypot(*(clearance.point_shaft[:2] - plant.shaft_centre))
        assert abs(plant.shaft_radius - radius - clearance.value) < 1e-12


def test_a_batchs_clearances_from_its_arrays_equal_those_of_its_solutions():
    """Rows the batch solved together, a single cable's swing (the fallback's), an unsolvable row."""
    plant = load_plant()
    lengths = random_lengths(40, seed=9)
    lengths[5] = [300.0, 304.0, 304.0, 304.0]   # one rope carries the platform alone
    lengths[11] = np.nan
    batch = solve_batch(plant, lengths)
    assert batch.fallback and not batch.ok.all()
    want = solution_clearances(plant, batch.solutions())
    for got, expected in zip(batch_clearances(plant, batch), want):
        assert (got is None) == (expected is None)
        if got is not None:
            assert (got.value, got.point_name) == (expected.value, expected.point_name)
            assert np.array_equal(got.point_shaft, expected.point_shaft)
