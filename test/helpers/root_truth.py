"""Equilibria computed without the package's solvers: the rigid weak mode, and elastic ropes.

Four taut rigid ropes hold the platform only where l1 + l3 = l2 + l4 (to the micrometre),
and there the load may be shared in a one-parameter family: which member the ropes carry
is what the load pins tell. Here the truth is the root of the balance written as forces
and moments on the platform (each rope pulls B_i towards A_i; moments about C), three
rope spans equal to chosen lengths, and the share along (-1, 1, -1, 1) set to a drawn
value; the fourth length is then the fourth span. Elastic ropes (Hooke, EA / L, with the
own-weight stretch L = l + w l^2 / (2 EA)) need only the six balance equations in the pose.
scipy's hybrid Powell root finder, scipy's rotations: nothing of cable_winch_monitor.model
but the plant's points.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import root
from scipy.spatial.transform import Rotation

WEAK = np.array([-1.0, 1.0, -1.0, 1.0])
BALANCE_TOL = 1e-8  # [m g, 10 m g m] force and moment left unbalanced: a millinewton


@dataclass(frozen=True)
class Truth:
    lengths: np.ndarray      # (4,) [m]
    tensions: np.ndarray     # (4,) [N]
    rotation: np.ndarray     # (3, 3)
    position: np.ndarray     # (3,) platform origin [m]
    roll: float
    pitch: float


def _balance(x: np.ndarray, plant, lengths3: np.ndarray, share: float) -> np.ndarray:
    rotation = Rotation.from_rotvec(x[3:6]).as_matrix()
    position, tensions = x[0:3], x[6:10] * plant.weight
    points = position + plant.attachments @ rotation.T
    point_c = position + rotation @ plant.cog
    pulls = plant.anchors - points
    spans = np.linalg.norm(pulls, axis=1)
    forces = tensions[:, None] * pulls / spans[:, None]
    force = forces.sum(axis=0) + np.array([0.0, 0.0, -plant.weight])
    moment = np.cross(points - point_c, forces).sum(axis=0)
    return np.concatenate([force / plant.weight, moment / (plant.weight * 10.0), spans[:3] - lengths3,
                           [(WEAK @ tensions - share) / plant.weight]])


def weak_mode_truth(plant, payout: float, offsets3: np.ndarray, share: float) -> Truth | None:
    """The four-taut equilibrium with l1..l3 = payout + offsets3 and WEAK . tau = share [N];
    None where the root finder fails or a tension would be negative."""
    lengths3 = payout + np.asarray(offsets3, dtype=float)
    start = np.concatenate([[0.0, 0.0, -payout], np.zeros(3), np.full(4, 0.25)])
    result = root(_balance, start, args=(plant, lengths3, share), method="hybr", options={"xtol": 1e-13})
    if np.abs(_balance(result.x, plant, lengths3, share)).max() > BALANCE_TOL:  # hybr may stop at round-off
        return None
    rotation = Rotation.from_rotvec(result.x[3:6]).as_matrix()
    position, tensions = result.x[0:3], result.x[6:10] * plant.weight
    if tensions.min() < 0.0:
        return None
    span4 = np.linalg.norm(plant.anchors[3] - position - rotation @ plant.attachments[3])
    roll, pitch, _ = Rotation.from_matrix(rotation).as_euler("xyz")
    return Truth(np.append(lengths3, span4), tensions, rotation, position, float(roll), float(pitch))


def weak_mode_samples(plant, count: int, seed: int) -> list[Truth]:
    """`count` truths at payouts of 20-600 m, synchronisation errors up to 5 cm, shares up to 40 kN."""
    rng = np.random.default_rng(seed)
    out: list[Truth] = []
    while len(out) < count:
        truth = weak_mode_truth(plant, rng.uniform(20.0, 600.0), rng.uniform(-0.05, 0.05, 3),
                                rng.uniform(-40e3, 40e3))
        if truth is not None:
            out.append(truth)
    return out


def _elastic_balance(x: np.ndarray, plant, effective: np.ndarray, ea: float) -> np.ndarray:
    rotation = Rotation.from_rotvec(x[3:6]).as_matrix()
    points = x[0:3] + plant.attachments @ rotation.T
    pulls = plant.anchors - points
    spans = np.linalg.norm(pulls, axis=1)
    tensions = ea / effective * np.maximum(spans - effective, 0.0)
    forces = tensions[:, None] * pulls / spans[:, None]
    force = forces.sum(axis=0) + np.array([0.0, 0.0, -plant.weight])
    moment = np.cross(points - (x[0:3] + rotation @ plant.cog), forces).sum(axis=0)
    return np.concatenate([force / plant.weight, moment / (plant.weight * 10.0)])


def elastic_truth(plant, lengths: np.ndarray, ea: float, weight: float) -> Truth | None:
    """Equilibrium on four elastic ropes of unstretched lengths l, EA [N] and weight w [N/m]; None where
    the root finder fails or fewer than two ropes pull."""
    lengths = np.asarray(lengths, dtype=float)
    effective = lengths + weight * lengths ** 2 / (2.0 * ea)
    sag = plant.weight * effective.max() / (2.0 * ea)
    start = np.concatenate([[0.0, 0.0, -effective.mean() - sag], np.zeros(3)])
    result = root(_elastic_balance, start, args=(plant, effective, ea), method="hybr", options={"xtol": 1e-13})
    if not result.success or np.abs(_elastic_balance(result.x, plant, effective, ea)).max() > 1e-9:
        return None
    rotation = Rotation.from_rotvec(result.x[3:6]).as_matrix()
    spans = np.linalg.norm(plant.anchors - result.x[0:3] - plant.attachments @ rotation.T, axis=1)
    tensions = ea / effective * np.maximum(spans - effective, 0.0)
    if np.count_nonzero(tensions) < 2:
        return None
    roll, pitch, _ = Rotation.from_matrix(rotation).as_euler("xyz")
    return Truth(lengths, tensions, rotation, result.x[0:3].copy(), float(roll), float(pitch))


def _three_balance(x: np.ndarray, plant, lengths: np.ndarray, taut: np.ndarray) -> np.ndarray:
    rotation = Rotation.from_rotvec(x[3:6]).as_matrix()
    position, tensions = x[0:3], np.zeros(4)
    tensions[taut] = x[6:9] * plant.weight
    points = position + plant.attachments @ rotation.T
    pulls = plant.anchors - points
    spans = np.linalg.norm(pulls, axis=1)
    forces = tensions[:, None] * pulls / spans[:, None]
    force = forces.sum(axis=0) + np.array([0.0, 0.0, -plant.weight])
    moment = np.cross(points - (position + rotation @ plant.cog), forces).sum(axis=0)
    return np.concatenate([force / plant.weight, moment / (plant.weight * 10.0), spans[taut] - lengths[taut]])


def slack_truth(plant, lengths: np.ndarray, slack: int, excess: float) -> Truth | None:
    """Rigid ropes with rope `slack` (0-based) slack: the other three at `lengths`, the slack one
    `excess` [m] longer than its span; None where the root finder fails or a taut rope would push."""
    lengths = np.asarray(lengths, dtype=float).copy()
    taut = np.arange(4) != slack
    start = np.concatenate([[0.0, 0.0, -lengths[taut].mean()], np.zeros(3), np.full(3, 1.0 / 3.0)])
    result = root(_three_balance, start, args=(plant, lengths, taut), method="hybr", options={"xtol": 1e-13})
    if np.abs(_three_balance(result.x, plant, lengths, taut)).max() > BALANCE_TOL:
        return None
    rotation = Rotation.from_rotvec(result.x[3:6]).as_matrix()
    tensions = np.zeros(4)
    tensions[taut] = result.x[6:9] * plant.weight
    if tensions.min() < 0.0:
        return None
    position = result.x[0:3].copy()
    lengths[slack] = np.linalg.norm(plant.anchors[slack] - position - rotation @ plant.attachments[slack]) + excess
    roll, pitch, _ = Rotation.from_matrix(rotation).as_euler("xyz")
    return Truth(lengths, tensions, rotation, position, float(roll), float(pitch))
