"""Rigid-body geometry of the platform: poses, cable spans and the structure matrix of eq. (8)."""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..plantfile.plant import Plant


def skew(v: np.ndarray) -> np.ndarray:
    """[v]x, the cross-product matrix; for stacked vectors (..., 3) the stack (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    if v.ndim == 1:  # the per-sample solvers' hot path: three times faster than the stacked form
        return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    return out - np.swapaxes(out, -1, -2)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b for 3-vectors or rows of (n, 3) arrays; np.cross costs ten times more on such small arrays."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
                     a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def rotation_from_vector(omega: np.ndarray) -> np.ndarray:
    """exp([omega]x): rotation by |omega| about omega (Rodrigues)."""
    angle = float(np.linalg.norm(omega))
    if angle < 1e-12:
        return np.eye(3) + skew(omega)
    k = skew(omega / angle)
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * (k @ k)


def rotations_from_vectors(omega: np.ndarray) -> np.ndarray:
    """exp([omega]x) for stacked rotation vectors (n, 3): `rotation_from_vector` of each row, together."""
    angle = np.linalg.norm(omega, axis=1)
    small = angle < 1e-12
    k = skew(omega / np.where(small, 1.0, angle)[:, None])
    exact = np.eye(3) + np.sin(angle)[:, None, None] * k + (1.0 - np.cos(angle))[:, None, None] * (k @ k)
    return np.where(small[:, None, None], np.eye(3) + skew(omega), exact)


def rotation_about_z(angle: float) -> np.ndarray:
    """Rotation by angle [rad] about the shaft's vertical axis."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rotation_aligning(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The smallest rotation turning direction `source` into direction `target`."""
    s = source / np.linalg.norm(source)
    t = target / np.linalg.norm(target)
    axis = np.cross(s, t)
    sin_angle, cos_angle = np.linalg.norm(axis), float(np.dot(s, t))
    if sin_angle < 1e-15:
        if cos_angle > 0.0:
            return np.eye(3)
        ortho = np.cross(s, [1.0, 0.0, 0.0] if abs(s[0]) < 0.9 else [0.0, 1.0, 0.0])
        return rotation_from_vector(np.pi * ortho / np.linalg.norm(ortho))
    return rotation_from_vector(axis / sin_angle * np.arctan2(sin_angle, cos_angle))


def quaternions_from_rotations(rotations: np.ndarray) -> np.ndarray:
    """Unit quaternions (x, y, z, w), w >= 0, of rotation matrices (n, 3, 3), (n, 4) (Shepperd's method: from
    the trace where it is positive, else from the largest diagonal element, the first of equal ones)."""
    m = np.asarray(rotations, dtype=float).reshape(-1, 3, 3)
    q = np.empty((len(m), 4))
    trace = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    by_trace = trace > 0.0
    r = m[by_trace]
    s = 2.0 * np.sqrt(trace[by_trace] + 1.0)
    q[by_trace] = np.column_stack([(r[:, 2, 1] - r[:, 1, 2]) / s, (r[:, 0, 2] - r[:, 2, 0]) / s,
                                   (r[:, 1, 0] - r[:, 0, 1]) / s, 0.25 * s])
    largest = np.argmax(np.diagonal(m, axis1=1, axis2=2), axis=1)
    for i in range(3):
        rows = ~by_trace & (largest == i)
        if not rows.any():
            continue
        j, k = (i + 1) % 3, (i + 2) % 3
        r = m[rows]
        s = 2.0 * np.sqrt(1.0 + r[:, i, i] - r[:, j, j] - r[:, k, k])
        part = np.empty((len(r), 4))
        part[:, i], part[:, j], part[:, k] = 0.25 * s, (r[:, j, i] + r[:, i, j]) / s, (r[:, k, i] + r[:, i, k]) / s
        part[:, 3] = (r[:, k, j] - r[:, j, k]) / s
        q[rows] = part
    norm = np.sqrt(q[:, 0] * q[:, 0] + q[:, 1] * q[:, 1] + q[:, 2] * q[:, 2] + q[:, 3] * q[:, 3])
    return q / (norm * np.where(q[:, 3] >= 0.0, 1.0, -1.0))[:, None]


def quaternion_from_rotation(rotation: np.ndarray) -> np.ndarray:
    """`quaternions_from_rotations` of one rotation matrix, (4,), on Python floats: the live node converts a pose
    at every sample, in a sixteenth of numpy's time for one (test_geometry.py holds the two to the same bits)."""
    m = rotation.tolist()
    trace = m[0][0] + m[1][1] + m[2][2]
    if trace > 0.0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = [(m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s, 0.25 * s]
    else:
        i = max(range(3), key=lambda k: m[k][k])
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(1.0 + m[i][i] - m[j][j] - m[k][k])
        q = [0.0] * 4
        q[i] = 0.25 * s
        q[j] = (m[j][i] + m[i][j]) / s
        q[k] = (m[k][i] + m[i][k]) / s
        q[3] = (m[k][j] - m[j][k]) / s
    norm = math.sqrt(sum(v * v for v in q)) * (1.0 if q[3] >= 0.0 else -1.0)
    return np.array([v / norm for v in q])


def roll_pitch_yaw(rotation: np.ndarray) -> tuple[float, float, float]:
    """Roll, pitch, yaw [rad] of a rotation (REP-103 fixed-axis x-y-z convention)."""
    (r00, _, _), (r10, _, _), (r20, r21, r22) = rotation.tolist()
    return math.atan2(r21, r22), math.asin(min(1.0, max(-1.0, -r20))), math.atan2(r10, r00)


def roll_pitch_of_quaternion(quaternion_xyzw: Sequence[float]) -> tuple[float, float]:
    """Roll and pitch [rad] of a quaternion (x, y, z, w), as `roll_pitch_yaw` of its rotation
    matrix gives them (the quaternion is normalised first)."""
    x, y, z, w = (float(v) for v in quaternion_xyzw)
    n2 = x * x + y * y + z * z + w * w
    return (math.atan2(2.0 * (y * z + x * w) / n2, 1.0 - 2.0 * (x * x + y * y) / n2),
            math.asin(min(1.0, max(-1.0, -2.0 * (x * z - y * w) / n2))))


def fit_rotation(body: np.ndarray, world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares rigid transform (Kabsch) with world ~ position + rotation @ body."""
    body_centre, world_centre = body.mean(axis=0), world.mean(axis=0)
    h = (body - body_centre).T @ (world - world_centre)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rotation = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return rotation, world_centre - rotation @ body_centre


def attachment_points(plant: Plant, rotation: np.ndarray, position: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The attachments B_i (N, 4, 3) and the centre of gravity C (N, 3) in `shaft` of N stacked poses (rotations
    (N, 3, 3), positions (N, 3))."""
    return position[:, None, :] + plant.attachments @ np.swapaxes(rotation, -1, -2), position + rotation @ plant.cog


def structure_matrix(plant: Plant, points_b: np.ndarray, point_c: np.ndarray) -> np.ndarray:
    """J^T of eq. (8): column i is (u_i, CB_i x u_i), u_i the unit vector of A_i B_i. Shape (6, 4),
    or (..., 6, 4) for stacked points (..., 4, 3) and (..., 3).

    A cable pulls B_i towards A_i with tau_i (-u_i); the balance with gravity then reads
    J^T tau = F, F = (0, 0, -mg, 0, 0, 0), as in eq. (7). Moments are taken about C.
    """
    spans = points_b - plant.anchors
    units = spans / np.linalg.norm(spans, axis=-1, keepdims=True)
    moments = cross(points_b - point_c[..., None, :], units)
    return np.swapaxes(np.concatenate([units, moments], axis=-1), -1, -2)


def wrench_residuals(plant: Plant, points_b: np.ndarray, point_c: np.ndarray, tensions: np.ndarray,
                     load: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Force and moment imbalance of J^T tau = F, relative to |f| and |f| * max|CB_i|, for stacked
    samples: points (..., 4, 3) and (..., 3), tensions (..., 4), loads (6,) or (..., 6) (None: gravity)."""
    load = plant.wrench if load is None else np.asarray(load, dtype=float)
    imbalance = (structure_matrix(plant, points_b, point_c) @ tensions[..., None])[..., 0] - load
    scale = np.linalg.norm(load[..., :3], axis=-1)
    force = np.linalg.norm(imbalance[..., :3], axis=-1) / scale
    moment = np.linalg.norm(imbalance[..., 3:], axis=-1) / (scale * plant.moment_scale)
    return force, moment


def wrench_residual(plant: Plant, points_b: np.ndarray, point_c: np.ndarray, tensions: np.ndarray,
                    load: np.ndarray | None = None) -> tuple[float, float]:
    """`wrench_residuals` of one sample, as floats."""
    force, moment = wrench_residuals(plant, points_b, point_c, tensions, load)
    return float(force), float(moment)
