"""Pulleys of any orientation (tangent point, wrapped arc) and the sensor-calibration effects."""
from __future__ import annotations

import numpy as np
import pytest

from cable_winch_monitor.effects import PlantModel, available, effect_class
from cable_winch_monitor.effects.pulley import wrap
from cable_winch_monitor.model.conditions import Conditions
from cable_winch_monitor.model.plantfile.plant import PlantConfigError, Sheave, load_plant, plant_from_mapping
from cable_winch_monitor.paths import lab_plant_file

LAB_FILE = lab_plant_file()
RADIUS = 0.03


def _path_length(entry, axis, plane, radius, point_b, alpha):
    """Rope length from the entry point around the pulley to leave at angle alpha, then straight to B."""
    tangent = entry + radius * (1.0 + np.cos(alpha)) * plane + radius * np.sin(alpha) * axis
    theta = (alpha - np.pi + np.pi / 2.0) % (2.0 * np.pi) - np.pi / 2.0
    return radius * theta + np.linalg.norm(point_b - tangent)


@pytest.mark.parametrize("axis, swivel", [((0, 0, -1), True), ((0, 0, 1), True), ((1, 0, 0), False),
                                          ((0.3, -0.2, -1.0), True)])
def test_rope_leaves_at_the_tangent_point_of_the_shortest_path(axis, swivel):
    """A taut rope leaves a pulley where its span is perpendicular to the radius: the arc plus the span is
    stationary in the leaving angle there, and leaving earlier would cut through the pulley."""
    rng = np.random.default_rng(3)
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    towards = None if swivel else np.array([0.0, 0.0, -1.0])
    lab = load_plant(LAB_FILE)
    plant = lab.with_changes(sheaves=(Sheave(RADIUS, axis, swivel, towards),) * 4)
    for _ in range(20):
        points_b = lab.anchors * 0.3 + rng.uniform(-0.3, 0.3, (4, 3)) + np.array([0.0, 0.0, -1.2])
        if not swivel:
            points_b[:, 1] = lab.anchors[:, 1]  # in the fixed pulley's plane
        lengths = np.full(4, 2.0)
        tangents, spans, theta = wrap(plant, lengths, points_b)
        for i in range(4):
            if swivel:
                offset = points_b[i] - lab.anchors[i]
                plane = offset - offset @ axis * axis
            else:
                plane = towards
            plane = plane / np.linalg.norm(plane)
            centre = lab.anchors[i] + RADIUS * plane
            tangent = tangents[i]
            assert np.linalg.norm(tangent - centre) == pytest.approx(RADIUS, abs=1e-12)
            assert (points_b[i] - tangent) @ (tangent - centre) == pytest.approx(0.0, abs=1e-12)
            alpha = np.arctan2((tangent - centre) @ axis, (tangent - centre) @ plane)
            best = _path_length(lab.anchors[i], axis, plane, RADIUS, points_b[i], alpha)
            slope = (_path_length(lab.anchors[i], axis, plane, RADIUS, points_b[i], alpha + 1e-4)
                     - _path_length(lab.anchors[i], axis, plane, RADIUS, points_b[i], alpha - 1e-4)) / 2e-4
            assert abs(slope) < 1e-6 * RADIUS  # the length is stationary in the leaving angle ...
            early = lab.anchors[i] + RADIUS * (1.0 + np.cos(alpha - 0.05)) * plane + RADIUS * np.sin(alpha - 0.05) * axis
            direction = (points_b[i] - early) / np.linalg.norm(points_b[i] - early)
            closest = early + ((centre - early) @ direction) * direction
            assert (centre - early) @ direction > 0.0 and np.linalg.norm(closest - centre) < RADIUS  # ... and
            # leaving earlier would cut through the pulley
            assert lengths[i] - spans[i] == pytest.approx(RADIUS * theta[i])
            assert np.linalg.norm(points_b[i] - tangent) + RADIUS * theta[i] == pytest.approx(best)


def test_rope_up_a_post_wraps_half_a_turn_when_hanging_straight_down():
    lab = load_plant(LAB_FILE)
    radius = lab.sheaves[0].radius
    below_far_side = lab.anchors + np.array([[-2 * radius * np.sign(a[0]), 0.0, -1.0] for a in lab.anchors])
    tangents, spans, theta = wrap(lab, np.full(4, 1.5), below_far_side)
    assert theta == pytest.approx(np.full(4, np.pi), abs=1e-9)
    assert spans == pytest.approx(1.5 - np.pi * radius)
    assert np.linalg.norm(below_far_side - tangents, axis=1) == pytest.approx(np.ones(4), abs=1e-9)


def test_equilibrium_over_pulleys_balances_and_keeps_rope_lengths():
    """With the plant's pulleys, a taut rope's wrapped arc plus its span is the winch's length, the tensions
    pull along the spans from the tangent points, and they balance the weight."""
    model = PlantModel.from_plant(load_plant(LAB_FILE))
    for lengths in ([1.2, 1.2, 1.2, 1.2], [1.0, 1.3, 1.6, 1.3], [2.5, 2.2, 2.0, 2.3]):
        solution = model.solve(np.array(lengths))
        assert solution.ok
        tangents, spans, theta = wrap(model.physical, np.array(lengths), solution.points_b)
        vectors = tangents - solution.points_b
        distance = np.linalg.norm(vectors, axis=1)
        taut = solution.tensions > 1e-6
        assert np.all(solution.tensions >= 0.0)
        assert distance[taut] == pytest.approx(spans[taut], abs=1e-6)
        assert np.all(distance <= spans + 1e-6)  # slack ropes are not longer than their length
        assert np.all((theta > np.pi / 2) & (theta < np.pi))  # up the post, over, down and inwards
        force = (solution.tensions[:, None] * vectors / distance[:, None]).sum(axis=0)
        assert force == pytest.approx([0.0, 0.0, model.plant.weight], abs=1e-6 * model.plant.weight)


def test_pulley_radius_moves_the_platform_by_the_wrapped_arc():
    """Bigger pulleys take up more rope: the platform hangs higher by about r (theta - ...) for equal lengths."""
    base = load_plant(LAB_FILE)
    depths = [PlantModel(base.with_changes(sheaves=(Sheave(r, np.array([0.0, 0.0, -1.0])),) * 4))
              .solve(np.full(4, 1.5)).position[2] for r in (0.0, 0.03, 0.06)]
    assert depths[0] < depths[1] < depths[2]
    effect = effect_class("pulley_geometry")({"r": 0.06}, base)
    assert PlantModel(base, (effect,)).solve(np.full(4, 1.5)).position[2] == pytest.approx(depths[2], abs=1e-9)


@pytest.mark.parametrize("sheaves, message", [
    ({"radius": -0.1}, "must not be negative"),
    ({"radius": 0.03, "axis": [0, 0, 0]}, "non-zero direction"),
    ({"radius": 0.03, "swivel": False}, "towards' is missing"),
    ({"radius": 0.03, "swivel": "yes"}, "true or false"),
    ([{"radius": 0.03}] * 3, "list of four"),
    ({"radius": 0.03, "size": 1}, "unknown key 'plant.geometry.sheaves.size'"),
])
def test_bad_sheaves_name_the_key(sheaves, message):
    config = {"plant": {"mass": 13.0, "g": 9.81, "geometry": {
        "anchors": [[1, 1, 0], [-1, 1, 0], [-1, -1, 0], [1, -1, 0]],
        "attachments": [[0.1, 0.1, 0], [-0.1, 0.1, 0], [-0.1, -0.1, 0], [0.1, -0.1, 0]],
        "centre_of_gravity": [0, 0, -0.1], "sheaves": sheaves}}}
    with pytest.raises(PlantConfigError, match=message):
        plant_from_mapping(config)


def test_inclinometer_offset_and_load_pin_calibration_read_as_documented():
    lab = load_plant(LAB_FILE)
    model = PlantModel.from_plant(lab)
    solution = model.solve(np.array([1.0, 1.3, 1.6, 1.3]))
    plain = model.predict(solution)
    offset = effect_class("inclinometer_offset")({"roll": 0.02, "pitch": -0.01}, lab)
    calibration = effect_class("load_pin_calibration")({"zero_1": 1.5, "gain_1": 0.05, "gain_3": -0.1,
                                                         "zero_4": -2.0}, lab)
    read = model.with_effects([offset, calibration]).predict(solution, Conditions())
    assert read["roll"] == pytest.approx(plain["roll"] + 0.02) and read["pitch"] == pytest.approx(plain["pitch"] - 0.01)
    assert read["tension_cable_1"] == pytest.approx(1.05 * plain["tension_cable_1"] + 1.5)
    assert read["tension_cable_2"] == pytest.approx(plain["tension_cable_2"])
    assert read["tension_cable_3"] == pytest.approx(0.9 * plain["tension_cable_3"])
    assert read["tension_cable_4"] == pytest.approx(plain["tension_cable_4"] - 2.0)
    assert read["depth"] == plain["depth"]


@pytest.mark.parametrize("name", ["inclinometer_offset", "load_pin_calibration", "pulley_geometry"])
def test_new_effects_are_documented_like_the_others(name):
    cls = available()[name]
    assert cls.__doc__ and "Residual signature" in cls.__doc__
    assert cls.title and cls.signature and cls.source and cls.fittable()
