"""Pulleys of any orientation, fixed or swivelling: the rope wraps an arc and leaves at a tangent point.

A rope arrives at pulley i along its axis u_i (pointing back towards the winch) and touches
it at the anchor E_i; the pulley's centre is O_i = E_i + r n_i, n_i in the pulley's plane
and perpendicular to u_i. A swivelling pulley turns about u_i so that its plane holds the
attachment B_i: n_i is the part of B_i - E_i perpendicular to u_i, normalised; a fixed one
keeps the n_i of the plant file. In the plane (x along n_i, y along u_i) the rope runs
along y < 0 into the pulley, wraps the angle theta_i and leaves at the tangent point

    T_i = E_i + r (1 + cos alpha_i) n_i + r sin alpha_i u_i,   alpha_i = psi_i - acos(r / rho_i),
    theta_i = alpha_i - pi   (in [-pi/2, 3 pi/2)),

where (rho_i, psi_i) are the polar coordinates of B_i - O_i in the plane (tangent condition
(B - T) . (T - O) = 0, the rope leaving in the direction of wrapping); the out-of-plane
part of a fixed pulley's rope (its fleet angle) is ignored. The winch's length counts from
E_i, so the free span from T_i is l_i - r theta_i. Solved by fixed-point iteration on the
pose (PlantModel).
"""
from __future__ import annotations

import numpy as np

from ..model.plantfile.plant import Plant, Sheave
from .base import Effect, Parameter, relative, relative_bounds, span

AXIS_FROM_BELOW = np.array([0.0, 0.0, -1.0])  # a rope running up a post from a winch at its foot


def _in_plane(sheaves: tuple[Sheave, ...], offsets: np.ndarray) -> np.ndarray:
    """n_i of each pulley for the attachment offsets B_i - E_i (..., 4, 3) (swivelling: towards B_i)."""
    axis = np.array([s.axis for s in sheaves])
    perpendicular = offsets - np.sum(offsets * axis, axis=-1, keepdims=True) * axis
    # the rope runs along the axis: any plane will do
    fallback = np.cross(axis, np.where(np.abs(axis[:, :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]))
    norms = np.linalg.norm(perpendicular, axis=-1, keepdims=True)
    perpendicular = np.where(norms < 1e-12, fallback, perpendicular)
    swivelling = perpendicular / np.linalg.norm(perpendicular, axis=-1, keepdims=True)
    fixed = np.array([s.towards if not s.swivel else np.zeros(3) for s in sheaves])
    return np.where(np.array([s.swivel for s in sheaves])[:, None], swivelling, fixed)


def wrap(plant: Plant, lengths: np.ndarray, points_b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tangent points T_i (..., 4, 3), free spans l - r theta (..., 4) and wrap angles theta [rad] of the
    plant's pulleys for attachments at `points_b` (..., 4, 3) in the shaft frame and lengths (..., 4)
    counted from the plant's anchors E_i; stacked samples along the leading axes."""
    sheaves = plant.sheaves
    radius = np.array([s.radius for s in sheaves])
    axis = np.array([s.axis for s in sheaves])
    offsets = points_b - plant.anchors
    plane = _in_plane(sheaves, offsets)
    p_x, p_y = np.sum(offsets * plane, axis=-1) - radius, np.sum(offsets * axis, axis=-1)
    rho, psi = np.hypot(p_x, p_y), np.arctan2(p_y, p_x)
    alpha = psi - np.arccos(np.clip(radius / np.maximum(rho, 1e-12), -1.0, 1.0))
    theta = (alpha - np.pi + np.pi / 2.0) % (2.0 * np.pi) - np.pi / 2.0
    tangent = plant.anchors + (radius * (1.0 + np.cos(alpha)))[..., None] * plane \
        + (radius * np.sin(alpha))[..., None] * axis
    return tangent, lengths - radius * theta, theta


def _default_radius(plant: Plant) -> float:
    return float(np.mean([s.radius for s in plant.sheaves])) if plant.sheaves else 0.01 * span(plant)


class PulleyGeometry(Effect):
    """The ropes wrap pulleys of radius r, fixed or swivelling about any axis (see the module's formulas).

    With the plant file's `geometry.sheaves` it sets the radius of the pulleys described
    there; a plant without them gets four pulleys alike, swivelling (or fixed with their
    plane towards the plant's centre) about the axis (axis_x, axis_y, axis_z). The plant's
    anchors are where the ropes meet the pulleys along their axes, and the winches' lengths
    count from there. Residual signature: errors that grow with the ropes' angle from the
    pulley axes -- the tangent point moves by up to 2 r and the wrapped arc adds r theta -- so
    depth and tilt errors change with the platform's position in the workspace.
    """

    name = "pulley_geometry"
    title = "the ropes wrap pulleys (fixed or swivelling): tangent points move, the wrapped arc adds length"
    acts = "geometry"
    parameters = (Parameter("r", "m", _default_radius, relative_bounds(0.0, 0.1, span), relative(0.002, span),
                            "pulley radius (to the rope axis)"),
                  Parameter("swivel", "-", 1.0, (0.0, 1.0), 1.0, "1: pulleys swivel about their axis, 0: fixed",
                            fit=False),
                  *(Parameter(f"axis_{c}", "-", float(v), (-1.0, 1.0), 0.1, f"{c} of the pulley axis towards the "
                              "winch (plants without geometry.sheaves)", fit=False) for c, v in zip("xyz", AXIS_FROM_BELOW)))
    signature = "depth and tilt errors growing with the ropes' angle from the pulley axes, changing across the workspace"
    source = "geometry of a rope wrapping a pulley (seed 000, Fig. 3; seed 004, eqs. 3-9), any pulley orientation"

    def _sheaves(self, plant: Plant) -> tuple[Sheave, ...]:
        if plant.sheaves:
            return tuple(Sheave(self["r"], s.axis, s.swivel, s.towards) for s in plant.sheaves)
        axis = np.array([self["axis_x"], self["axis_y"], self["axis_z"]])
        axis = axis / max(np.linalg.norm(axis), 1e-12)
        if self["swivel"] >= 0.5:
            return (Sheave(self["r"], axis),) * 4
        inward = np.column_stack([plant.shaft_centre - plant.anchors[:, :2], np.zeros(4)])
        inward -= (inward @ axis)[:, None] * axis
        return tuple(Sheave(self["r"], axis, False, v / np.linalg.norm(v)) for v in inward)

    def plant(self, plant: Plant) -> Plant:
        return plant.with_changes(sheaves=self._sheaves(plant))
