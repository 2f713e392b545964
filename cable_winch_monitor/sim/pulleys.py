"""The simulator's own pulleys: where a rope leaves its pulley, and how much rope the pulley holds.

A rope comes from its winch along the line through the anchor E_i in the direction -u_i (u_i,
the pulley's axis, points back towards the winch), meets the pulley at E_i and wraps it until
it leaves along a tangent towards the attachment B_i. The pulley's centre is O_i = E_i + r n_i,
n_i in the pulley's plane and across u_i: a swivelling pulley turns about the line through E_i
along u_i until its plane holds B_i (n_i along the part of B_i - E_i across u_i); a fixed one
keeps its own n_i. With k = n x u the normal of the plane (the wrap turns about +k), q the
in-plane part of B - O and h = sqrt(|q|^2 - r^2) the free tangent's length, the rope leaves at

    T = O + (r^2 q - r h k x q) / |q|^2,

the tangent point from which B lies ahead in the sense of wrapping (B - T along k x (T - O)).
B's part across the plane (a fixed pulley's fleet angle) does not move T: the rope leaves where
B - T is perpendicular to the radius T - O. The wrapped angle theta is the turn from E - O to
T - O about k, in [-pi/2, 3pi/2); the winch's length counts from E_i, so the rope below T is
l - r theta long. Written apart from the package's effects.pulley (polar angles and its own
plane construction there) so that each checks the other.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Pulleys:
    """Four pulleys: radius [m] (4,), axis (4, 3) unit towards the winch, and for a fixed pulley the unit
    direction from its anchor to its centre (4, 3); rows of NaN in `towards` swivel."""

    radius: np.ndarray
    axis: np.ndarray
    towards: np.ndarray

    @property
    def swivel(self) -> np.ndarray:
        return np.isnan(self.towards[:, 0])


def _unit(vectors: np.ndarray) -> np.ndarray:
    return vectors / np.linalg.norm(vectors, axis=-1, keepdims=True)


def _across(axis: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Unit part of `offsets` across `axis`; where an offset runs along the axis, any direction across it."""
    across = offsets - np.sum(offsets * axis, axis=-1, keepdims=True) * axis
    along = np.linalg.norm(across, axis=-1) < 1e-12
    if np.any(along):
        helper = np.where(np.abs(axis[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        across = np.where(along[..., None], np.cross(axis, helper), across)
    return _unit(across)


def pulley_exits(pulleys: Pulleys, anchors: np.ndarray, points_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where each rope leaves its pulley, and the wrapped angle theta [rad], for attachments B (..., 4, 3)."""
    r, u = pulleys.radius, pulleys.axis
    n = np.where(pulleys.swivel[:, None], _across(np.broadcast_to(u, points_b.shape), points_b - anchors),
                 pulleys.towards)
    centres = anchors + r[:, None] * n
    k = np.cross(n, u)
    q = points_b - centres
    q = q - np.sum(q * k, axis=-1, keepdims=True) * k
    q2 = np.sum(q * q, axis=-1)
    h = np.sqrt(np.maximum(q2 - r * r, 0.0))
    radial = ((r * r)[..., None] * q - (r * h)[..., None] * np.cross(k, q)) / q2[..., None]
    entry = -r[:, None] * n
    turn = np.arctan2(np.sum(np.cross(entry, radial) * k, axis=-1), np.sum(entry * radial, axis=-1))
    theta = (turn + 0.5 * np.pi) % (2.0 * np.pi) - 0.5 * np.pi
    return centres + radial, np.where(r > 0.0, theta, 0.0)
