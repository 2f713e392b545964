"""The simulator's pulleys (sim/pulleys.py) against a brute-force construction of the taut rope, and the
package's pulley effect (effects/pulley.py) against the simulator's: two formulations that must agree."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from cable_winch_monitor.effects import PlantModel
from cable_winch_monitor.effects.pulley import wrap
from cable_winch_monitor.model.plantfile.plant import Sheave, load_plant
from cable_winch_monitor.paths import lab_plant_file
from cable_winch_monitor.sim.equilibrium import Rig, Trajectory, imbalance
from cable_winch_monitor.sim.pulleys import Pulleys, pulley_exits
from cable_winch_monitor.sim.truth import plant_pulleys

LAB = load_plant(lab_plant_file())
POLYGON = 200_000  # vertices of the polygon standing for the pulley's circle


def _random_attachments(rng: np.random.Generator) -> np.ndarray:
    """Attachment points of a platform somewhere in the lab robot's workspace, tilted a little."""
    centre = np.array([*rng.uniform(-0.4, 0.4, 2), -rng.uniform(0.3, 2.3)])
    return centre + LAB.attachments + rng.normal(0.0, 0.02, (4, 3))


def _taut_string(entry: np.ndarray, centre: np.ndarray, plane: np.ndarray, axis: np.ndarray,
                 point_b: np.ndarray) -> float:
    """Shortest rope from the entry point to B that passes over the pulley (the side away from the winch):
    the hull of the circle, a point W on the incoming rope and B, walked from W to B over the pulley,
    less the incoming piece W-E."""
    radius = np.linalg.norm(entry - centre)
    angles = np.linspace(0.0, 2.0 * np.pi, POLYGON, endpoint=False)
    circle = radius * np.column_stack([np.cos(angles), np.sin(angles)])
    incoming = 1.0
    w = np.array([-radius, incoming])                                    # plane coordinates (along plane, axis)
    b = np.array([(point_b - centre) @ plane, (point_b - centre) @ axis])
    points = np.vstack([circle, w, b])
    hull = list(ConvexHull(points).vertices)                             # counter-clockwise
    i_w, i_b = hull.index(POLYGON), hull.index(POLYGON + 1)
    chains = [hull[i_w:] + hull[:i_w], hull[i_b:] + hull[:i_b]]
    chains = [chain[:chain.index(end) + 1] for chain, end in zip(chains, (POLYGON + 1, POLYGON))]
    over = min(chains, key=lambda chain: points[chain, 1].min())         # the one round the far side (axis < 0)
    path = points[over]
    return float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1))) - incoming


def test_rope_over_a_swivel_pulley_is_the_shortest_string():
    """Exit point and wrapped arc of the simulator give the length of the taut string around the pulley."""
    rng = np.random.default_rng(11)
    pulleys = plant_pulleys(LAB, None)
    for _ in range(10):
        points_b = _random_attachments(rng)
        exits, theta = pulley_exits(pulleys, LAB.anchors, points_b)
        for i in range(4):
            offset = points_b[i] - LAB.anchors[i]
            axis = pulleys.axis[i]
            plane = offset - (offset @ axis) * axis
            plane /= np.linalg.norm(plane)
            centre = LAB.anchors[i] + pulleys.radius[i] * plane
            simulated = pulleys.radius[i] * theta[i] + np.linalg.norm(points_b[i] - exits[i])
            assert simulated == pytest.approx(_taut_string(LAB.anchors[i], centre, plane, axis, points_b[i]),
                                              abs=1e-8)
            assert np.linalg.norm(exits[i] - centre) == pytest.approx(pulleys.radius[i], abs=1e-12)


def test_fixed_pulley_exit_is_where_the_rope_leaves_the_groove():
    """A fixed pulley with the rope at a fleet angle: the exit lies on the circle where the rope is
    perpendicular to the radius, found here by bisection on a dense scan of the circle."""
    rng = np.random.default_rng(12)
    axis = np.array([0.0, 0.0, -1.0])
    towards = np.array([-1.0, 0.2, 0.0]) / np.hypot(1.0, 0.2)
    pulleys = Pulleys(np.full(4, 0.05), np.tile(axis, (4, 1)), np.tile(towards, (4, 1)))
    anchors = LAB.anchors * np.array([1.0, 1.0, 0.0])
    for _ in range(10):
        points_b = anchors + np.column_stack([-rng.uniform(0.5, 1.2, 4), rng.uniform(-0.3, 0.3, 4),
                                              -rng.uniform(0.3, 2.0, 4)])
        exits, theta = pulley_exits(pulleys, anchors, points_b)
        for i in range(4):
            centre = anchors[i] + 0.05 * towards
            phi = np.linspace(0.0, np.pi, 100_001)  # from the entry (-towards) over the far side (-axis)
            circle = centre - 0.05 * (np.cos(phi)[:, None] * towards + np.sin(phi)[:, None] * axis)
            leaving = np.sum((points_b[i] - circle) * (circle - centre), axis=1)
            k = int(np.flatnonzero(np.diff(np.sign(leaving)))[0])
            exact = phi[k] - leaving[k] * (phi[k + 1] - phi[k]) / (leaving[k + 1] - leaving[k])
            assert theta[i] == pytest.approx(exact, abs=1e-8)
            assert exits[i] == pytest.approx(centre - 0.05 * (np.cos(exact) * towards + np.sin(exact) * axis),
                                             abs=1e-9)


@pytest.mark.parametrize("swivel", [True, False])
def test_package_pulley_effect_agrees_with_the_simulator(swivel):
    """effects/pulley.py and sim/pulleys.py, formulated apart, give the same exits and free spans (1e-6 m)
    on random poses, swivelling pulleys and fixed ones with fleet angles."""
    rng = np.random.default_rng(13)
    axis = np.array([0.1, -0.2, -1.0]) / np.linalg.norm([0.1, -0.2, -1.0])
    sheaves = []
    for anchor in LAB.anchors:
        inward = -anchor - (-anchor @ axis) * axis
        sheaves.append(Sheave(0.03, axis) if swivel else Sheave(0.03, axis, False, inward / np.linalg.norm(inward)))
    plant = LAB.with_changes(sheaves=tuple(sheaves))
    pulleys = plant_pulleys(plant, None)
    for _ in range(200):
        points_b = _random_attachments(rng)
        lengths = np.linalg.norm(points_b - plant.anchors, axis=1) + 0.1
        tangents, free, _ = wrap(plant, lengths, points_b)
        exits, theta = pulley_exits(pulleys, plant.anchors, points_b)
        assert np.abs(tangents - exits).max() < 1e-6
        assert np.abs(free - (lengths - 0.03 * theta)).max() < 1e-6


def test_truth_over_pulleys_matches_the_package_solve():
    """The simulator's root-found equilibrium over the lab robot's swivel pulleys and the package's solve
    (fixed-point iteration on the tangent points): same taut ropes, points within 1e-6 m, tensions within
    1e-4 N, and the truth balances."""
    plant = LAB
    rig = Rig(anchors=plant.anchors, attachments=plant.attachments, cog=plant.cog, weight_scale=plant.weight,
              lever_scale=plant.moment_scale, pulleys=plant_pulleys(plant, None))
    model = PlantModel.from_plant(plant)
    trajectory = Trajectory(rig)
    rng = np.random.default_rng(14)
    for t in range(20):
        lengths = np.array([1.6, 1.6, 1.6, 1.6]) + rng.uniform(-0.3, 0.3) + rng.uniform(-0.05, 0.05, 4)
        state = trajectory(float(t), lengths, plant.wrench)
        force, moment = imbalance(state, plant.wrench)
        assert np.abs(force).max() < 1e-8 * plant.weight and np.abs(moment).max() < 1e-8 * plant.weight
        assert np.all(state.tensions >= 0.0)
        package = model.solve(lengths)
        assert package.ok and np.array_equal(state.taut, package.taut)
        assert np.abs(state.points_b - package.points_b).max() < 1e-6
        assert np.abs(state.tensions - package.tensions).max() < 1e-4
