"""What the wall clearance is based on: the measured tilt, the model, or both, and how far they disagree.

On this platform the clearance is the tilt: four near-vertical ropes keep the attachments'
centroid within millimetres of the shaft axis, so an inclinometer of 0.01 deg gives the
clearance of a deck 12 m below to about 2 mm. The estimate follows the measured tilt
where the inclinometer is fused; the model's own prediction (the reported lengths with
its expected error) is compared with it. Where they disagree beyond their spread, the
measured tilt stands where the load pins fused with it agree with it; where nothing else
confirms it, the alarm takes the more dangerous of the two, and says so. Where no tilt is
measured, the clearance is the model's ("model only").
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..frozen import fast_init
from ..model.plantfile.plant import Plant
from .clearance import Clearance

SIGMAS = 3.0  # the two clearances disagree when further apart than this many of their combined 1-sigma
CORROBORATING_PINS = 3  # load pins fused with the inclinometer that confirm its tilt


@fast_init
@dataclass(frozen=True)
class Basis:
    """The clearance an alarm level is based on, and what it is based on in words."""

    clearance: Clearance | None
    text: str
    kind: str = ""  # the text without its numbers, where it has numbers: what replay summaries count (`summary`)

    @property
    def summary(self) -> str:
        return self.kind or self.text


@lru_cache(maxsize=16)
def _tilt_map(attachments: bytes) -> np.ndarray:
    """(2, 4) roll and pitch [rad] per metre of rope length added at each attachment: the plane through the
    four attachment points dropped by their ropes' extra length (small angles, near-vertical ropes)."""
    points = np.frombuffer(attachments).reshape(4, 3)
    design = np.column_stack([np.ones(4), points[:, 0], points[:, 1]])
    slopes = np.linalg.pinv(design)[1:]         # d z / d x, d z / d y of the plane per metre of height
    return np.vstack([-slopes[1], slopes[0]])   # a rope paid out further lowers its point: z = -length


def tilt_sigmas(plant: Plant, length_covariance: np.ndarray) -> np.ndarray:
    """The 1-sigma [rad] (largest over directions) of the tilt that lengths with these covariances (N, 4, 4)
    give, (N,)."""
    mapping = _tilt_map(np.ascontiguousarray(plant.attachments, dtype=float).tobytes())
    return np.sqrt(np.maximum(np.linalg.eigvalsh(mapping @ length_covariance @ mapping.T)[:, -1], 0.0))


def judged(measured: Clearance | None, model: Clearance | None, tilt_measured: bool, corroborated: bool,
           measured_sigma: float, model_sigma: float) -> Basis:
    """The basis of the alarm from the estimate's clearance (`measured`, following the measured tilt where
    `tilt_measured`) and the model's own, with their tilts' 1-sigma [rad]. Where they disagree beyond
    their combined spread: the measured one where the load pins fused with it are `corroborated` with it
    (a platform tilted otherwise would load them otherwise: its weight's moment), else the more
    dangerous of the two, since nothing tells which is wrong."""
    if measured is None:
        return Basis(model, "model only" if model is not None else "no clearance")
    if not tilt_measured:
        return Basis(measured, "model only (no tilt measured)")
    if model is None:
        return Basis(measured, "tilt measured; the model has no pose")
    lever = max(abs(float(measured.point_platform[2])), abs(float(model.point_platform[2])), 1.0)
    spread = SIGMAS * lever * math.hypot(measured_sigma, model_sigma)
    apart = model.value - measured.value
    if abs(apart) <= spread:
        return Basis(measured, "tilt measured; the model agrees")
    if apart < 0.0 and not corroborated:
        return Basis(model, f"the model's: {-apart:.3f} m closer at {model.point_name} than the measured tilt gives "
                            f"({measured.value:.3f} m), which no load pin confirms",
                     "the model's, closer than the measured tilt, which no load pin confirms")
    pins = ", the load pins agree" if corroborated else ""
    return Basis(measured, f"tilt measured{pins}; the model disagrees by {apart:+.3f} m at {model.point_name}",
                 f"tilt measured{pins}; the model disagrees")
