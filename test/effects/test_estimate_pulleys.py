"""The fused estimate where the geometry moves with the pose: ropes over the laboratory robot's swivel pulleys.

Truth is the simulator's equilibrium (root finding over its own pulley geometry, sim/pulleys.py
and sim/equilibrium.py), none of the package's solvers; the lab's sensors at their noise:
encoders 0.1 mm, load cells 0.3 N, AHRS 0.05 deg.
"""
from __future__ import annotations

import numpy as np
import pytest

from cable_winch_monitor import channels
from cable_winch_monitor.effects import PlantModel
from cable_winch_monitor.effects.estimate import estimate_recording
from cable_winch_monitor.effects.model import NO_CONDITIONS, REFINE_TOL
from cable_winch_monitor.model.estimator import States
from cable_winch_monitor.model.plantfile.plant import load_plant
from cable_winch_monitor.model.statics.geometry import roll_pitch_yaw
from cable_winch_monitor.model.statics.result import check_physics
from cable_winch_monitor.paths import lab_plant_file
from cable_winch_monitor.sim.equilibrium import Rig, Trajectory
from cable_winch_monitor.sim.truth import plant_pulleys

LAB = load_plant(lab_plant_file())
NOISE = {**LAB.noise, "length": 1e-4}
COUNT = 120


@pytest.fixture(scope="module")
def lowering():
    """Truths of a platform lowered and swung sideways through the workspace (cable 3 paid out 2 cm
    more: three taut cables, the taut set switching as it swings), and their noisy readings."""
    rig = Rig(anchors=LAB.anchors, attachments=LAB.attachments, cog=LAB.cog, weight_scale=LAB.weight,
              lever_scale=LAB.moment_scale, pulleys=plant_pulleys(LAB, None))
    trajectory = Trajectory(rig)
    t = np.linspace(0.0, 1.0, COUNT)
    swing = 0.12 * np.sin(2 * np.pi * t)[:, None] * np.array([1.0, -1.0, -1.0, 1.0])
    lengths = 1.3 + 0.8 * t[:, None] + swing + np.array([0.0, 0.0, 0.02, 0.0])
    truths = [trajectory(float(k), row, LAB.wrench) for k, row in enumerate(lengths)]
    rng = np.random.default_rng(21)
    reported = lengths + rng.normal(0.0, NOISE["length"], lengths.shape)
    pins = np.array([s.tensions for s in truths]) + rng.normal(0.0, NOISE["tension"], (COUNT, 4))
    angles = np.array([s.angles[:2] for s in truths]) + rng.normal(0.0, NOISE["roll"], (COUNT, 2))
    measured = {**{name: pins[:, i] for i, name in enumerate(channels.TENSION_CHANNELS)},
                "roll": angles[:, 0], "pitch": angles[:, 1]}
    return truths, lengths, reported, measured


def test_lengths_alone_are_the_forward_kinematics_over_the_pulleys(lowering):
    _, lengths, _, _ = lowering
    model = PlantModel.from_plant(LAB.with_changes(noise=NOISE))
    for row, fused in zip(lengths, estimate_recording(model, lengths, {}, [NO_CONDITIONS] * COUNT)):
        want = model.solve(row)
        assert fused.solution.taut_set == want.taut_set
        assert np.abs(fused.solution.points_b - want.points_b).max() < REFINE_TOL  # both iterate to this


def test_fused_tensions_and_pose_match_the_truth_and_balance_at_the_tangent_points(lowering):
    truths, _, reported, measured = lowering
    model = PlantModel.from_plant(LAB.with_changes(noise=NOISE))
    fused = estimate_recording(model, reported, measured, [NO_CONDITIONS] * COUNT)
    assert all(e.fused for e in fused)
    errors = np.array([e.solution.tensions - s.tensions for e, s in zip(fused, truths)])
    assert np.mean(np.abs(errors) <= 3.0 * NOISE["tension"]) >= 0.99
    forward = np.array([model.solve(row).tensions - s.tensions for row, s in zip(reported, truths)])
    assert np.sqrt(np.mean(errors ** 2)) < 0.5 * np.sqrt(np.mean(forward ** 2))  # the lengths alone: 0.18 N rms
    assert max(np.abs(e.solution.points_b - s.points_b).max() for e, s in zip(fused, truths)) < 5e-4
    assert sum(e.solution.taut_set != tuple(np.flatnonzero(s.taut) + 1) for e, s in zip(fused, truths)) <= 2
    for estimate in fused:
        solution = estimate.loaded_solution
        tangents, free = model.refine(estimate.reported[None], States.of(LAB, [solution]))
        check = check_physics(LAB.with_changes(anchors=tangents[0]), solution)
        assert check.force_residual < 1e-8 and check.moment_residual < 1e-8 and check.min_tension >= 0.0
        assert check.max_overstretch < 1e-9  # a slack cable's free span within its length
        # the free span plus the wrapped arc is the corrected length, the correction in sigma where it belongs
        assert np.abs(solution.lengths - (free[0] + estimate.corrections)).max() < 1e-6
        assert np.abs(estimate.corrections_sigma).max() < 5.0
    roll_pitch = np.array([roll_pitch_yaw(e.solution.rotation)[:2] for e in fused])
    assert np.abs(roll_pitch - np.array([s.angles[:2] for s in truths])).max() < 4.0 * NOISE["roll"]
