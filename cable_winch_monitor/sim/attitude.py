"""The inclinometer's attitude as its message carries it: a quaternion of roll and pitch."""
from __future__ import annotations

import numpy as np


def quaternion_from_roll_pitch(roll: float, pitch: float) -> tuple[float, float, float, float]:
    """(x, y, z, w) of the rotation with this roll and pitch and zero yaw (REP-103 x-y-z)."""
    cr, sr, cp, sp = np.cos(roll / 2), np.sin(roll / 2), np.cos(pitch / 2), np.sin(pitch / 2)
    return float(sr * cp), float(cr * sp), float(-sr * sp), float(cr * cp)
