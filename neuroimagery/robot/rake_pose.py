"""Quaternion helpers of the rake's kinematic drive (batched numpy, pybullet's (x, y, z, w) order)."""
from __future__ import annotations

import numpy as np


def quat_from_matrix(R: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) in pybullet's (x, y, z, w) order from rotation matrices (..., 3, 3)."""
    m = R
    t = np.stack([
        1 + m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2],
        1 + m[..., 0, 0] - m[..., 1, 1] - m[..., 2, 2],
        1 - m[..., 0, 0] + m[..., 1, 1] - m[..., 2, 2],
        1 - m[..., 0, 0] - m[..., 1, 1] + m[..., 2, 2],
    ], axis=-1)
    k = t.argmax(axis=-1)  # the numerically safest of the four branches
    s = np.sqrt(np.maximum(np.take_along_axis(t, k[..., None], -1)[..., 0], 1e-12)) * 2  # 4 * |component|
    qw = np.stack([(m[..., 2, 1] - m[..., 1, 2]) / s, (m[..., 0, 2] - m[..., 2, 0]) / s,
                   (m[..., 1, 0] - m[..., 0, 1]) / s, s / 4], -1)
    qx = np.stack([s / 4, (m[..., 0, 1] + m[..., 1, 0]) / s, (m[..., 0, 2] + m[..., 2, 0]) / s,
                   (m[..., 2, 1] - m[..., 1, 2]) / s], -1)
    qy = np.stack([(m[..., 0, 1] + m[..., 1, 0]) / s, s / 4, (m[..., 1, 2] + m[..., 2, 1]) / s,
                   (m[..., 0, 2] - m[..., 2, 0]) / s], -1)
    qz = np.stack([(m[..., 0, 2] + m[..., 2, 0]) / s, (m[..., 1, 2] + m[..., 2, 1]) / s, s / 4,
                   (m[..., 1, 0] - m[..., 0, 1]) / s], -1)
    q = np.select([k[..., None] == 0, k[..., None] == 1, k[..., None] == 2], [qw, qx, qy], qz)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def rotvec_between(q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
    """World-frame rotation vectors (..., 3) of the rotations taking q0 to q1 (q1 = r * q0)."""
    x0, y0, z0, w0 = -q0[..., 0], -q0[..., 1], -q0[..., 2], q0[..., 3]  # conjugate of q0
    x1, y1, z1, w1 = q1[..., 0], q1[..., 1], q1[..., 2], q1[..., 3]
    w = w1 * w0 - x1 * x0 - y1 * y0 - z1 * z0
    v = np.stack([w1 * x0 + x1 * w0 + y1 * z0 - z1 * y0,
                  w1 * y0 - x1 * z0 + y1 * w0 + z1 * x0,
                  w1 * z0 + x1 * y0 - y1 * x0 + z1 * w0], -1)
    sign = np.where(w < 0, -1.0, 1.0)[..., None]  # shortest way round
    v, w = v * sign, np.abs(w)
    n = np.linalg.norm(v, axis=-1)
    angle = 2 * np.arctan2(n, w)
    scale = np.where(n > 1e-12, angle / np.maximum(n, 1e-12), 2.0)
    return v * scale[..., None]

