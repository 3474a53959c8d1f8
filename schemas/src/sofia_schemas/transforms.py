"""Rigid transforms: validation, quaternions (x y z w), composition, inversion, interpolation, and
stamped poses looked up at a stamp (:class:`PoseTimeline`).

Rotations go through SciPy's ``Rotation`` (the calibrator's compiled fit has its own, for its loops).

Conventions: ``T_a_b`` is a (4, 4) homogeneous matrix mapping points in frame ``b`` into frame
``a``: ``p_a = T_a_b[:3, :3] @ p_b + T_a_b[:3, 3]``. Quaternions are ordered x y z w.
"""

from __future__ import annotations

from bisect import bisect_left, bisect_right
from typing import Protocol

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

ORTHONORMAL_TOL = 1e-6
QUAT_NORM_TOL = 1e-3


def as_transforms(T: np.ndarray, name: str = "T", tol: float = ORTHONORMAL_TOL) -> np.ndarray:
    """Validate (4, 4) or (n, 4, 4) rigid transforms and return them as float64.

    Raises ValueError naming ``name`` when the shape is wrong, a value is not finite, the rotation
    block is not orthonormal with determinant +1, or the last row is not ``[0, 0, 0, 1]``.
    """
    T = np.asarray(T, dtype=np.float64)
    if T.shape[-2:] != (4, 4) or T.ndim not in (2, 3):
        raise ValueError(f"{name} must have shape (4, 4) or (n, 4, 4), got {T.shape}")
    if not np.all(np.isfinite(T)):
        nonfinite = np.argwhere(~np.isfinite(T.reshape(-1, 16)).all(axis=1)).ravel().tolist()
        raise ValueError(f"{name} has non-finite values (matrices {nonfinite})")
    Ts = T.reshape(-1, 4, 4)
    R = Ts[:, :3, :3]
    err = np.abs(np.einsum("nji,njk->nik", R, R) - np.eye(3)).max(axis=(1, 2))
    det = np.linalg.det(R)
    bad = np.flatnonzero((err > tol) | (det < 0))
    if bad.size:
        raise ValueError(
            f"{name}: rotation block of matrix {int(bad[0])} is not a rotation "
            f"(|R^T R - I| = {err[bad[0]]:.2e}, det = {det[bad[0]]:.4f})"
        )
    last = np.abs(Ts[:, 3, :] - np.array([0.0, 0.0, 0.0, 1.0])).max(axis=1)
    bad = np.flatnonzero(last > tol)
    if bad.size:
        raise ValueError(
            f"{name}: last row of matrix {int(bad[0])} is {Ts[bad[0], 3].tolist()}, expected [0, 0, 0, 1]"
        )
    return T


def as_points(p: np.ndarray, name: str = "points") -> np.ndarray:
    """Validate (n, 3) finite points and return them as float64."""
    p = np.asarray(p, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"{name} must have shape (n, 3), got {p.shape}")
    if not np.all(np.isfinite(p)):
        rows = np.flatnonzero(~np.isfinite(p).all(axis=1)).tolist()
        raise ValueError(f"{name} has non-finite values in rows {rows}")
    return p


def quat_xyzw_to_matrix(q_xyzw: np.ndarray, normalize_tol: float = QUAT_NORM_TOL) -> np.ndarray:
    """Rotation matrices from quaternions.

    q_xyzw: (4,) or (n, 4) float, order x y z w. Quaternions whose norm differs from 1 by more than
    ``normalize_tol`` raise ValueError (they are usually a column-order mistake); smaller errors are
    normalised. Returns (3, 3) or (n, 3, 3).
    """
    q = np.asarray(q_xyzw, dtype=np.float64)
    if q.shape[-1] != 4 or q.ndim not in (1, 2):
        raise ValueError(f"quaternion must have shape (4,) or (n, 4) in x y z w order, got {q.shape}")
    if not np.all(np.isfinite(q)):
        raise ValueError(f"quaternion has non-finite values: {q.tolist()}")
    norms = np.sqrt(np.sum(q * q, axis=-1, keepdims=True))
    bad = np.flatnonzero(np.abs(norms - 1.0) > normalize_tol)
    if bad.size:
        raise ValueError(
            f"quaternion {int(bad[0])} has norm {norms.ravel()[bad[0]]:.6f}, expected 1 (order is x y z w)"
        )
    return np.asarray(Rotation.from_quat(q).as_matrix())


def matrix_to_quat_xyzw(R: np.ndarray) -> np.ndarray:
    """Quaternions (x y z w, w >= 0) of (3, 3) or (n, 3, 3) rotation matrices: (4,) or (n, 4).

    SciPy's ``Rotation.from_matrix``: a matrix that is not quite orthonormal is projected onto the
    rotations; a reflection or a non-finite matrix raises ValueError.
    """
    q = Rotation.from_matrix(np.asarray(R, dtype=np.float64)).as_quat()
    return np.where(q[..., 3:4] < 0, -q, q)


def make_transform(translation: np.ndarray, q_xyzw: np.ndarray) -> np.ndarray:
    """(4, 4) or (n, 4, 4) transforms from translations (…, 3) and quaternions (…, 4) x y z w."""
    t = np.asarray(translation, dtype=np.float64)
    R = quat_xyzw_to_matrix(q_xyzw)
    T = np.zeros((*R.shape[:-2], 4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = t
    T[..., 3, 3] = 1.0
    return T


def invert(T_a_b: np.ndarray) -> np.ndarray:
    """Inverse of (…, 4, 4) rigid transforms: ``T_b_a``."""
    T_a_b = np.asarray(T_a_b, dtype=np.float64)
    R_t = np.swapaxes(T_a_b[..., :3, :3], -1, -2)
    T_b_a = np.zeros_like(T_a_b)
    T_b_a[..., :3, :3] = R_t
    T_b_a[..., :3, 3] = -np.einsum("...ij,...j->...i", R_t, T_a_b[..., :3, 3])
    T_b_a[..., 3, 3] = 1.0
    return T_b_a


def apply(T_a_b: np.ndarray, p_b: np.ndarray) -> np.ndarray:
    """Map points: ``p_a = R_a_b p_b + t_a_b``.

    T_a_b: (4, 4), or (n, 4, 4) paired with p_b (n, 3). p_b: (..., 3). Returns points in frame a.
    """
    T_a_b = np.asarray(T_a_b, dtype=np.float64)
    p_b = np.asarray(p_b)
    if T_a_b.ndim == 2:
        return p_b @ T_a_b[:3, :3].T + T_a_b[:3, 3]
    return np.einsum("nij,nj->ni", T_a_b[:, :3, :3], p_b) + T_a_b[:, :3, 3]


def rpy_from_matrix(R: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw (radians; extrinsic x-y-z, as ROS ``tf``) of (3, 3) or (n, 3, 3) rotations."""
    return Rotation.from_matrix(np.asarray(R, dtype=np.float64)).as_euler("xyz")


def rotation_angle(R: np.ndarray) -> np.ndarray:
    """Angle (radians) of (…, 3, 3) rotations."""
    tr = np.trace(np.asarray(R), axis1=-2, axis2=-1)
    return np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0))


def pose_gap(T_a: np.ndarray, T_b: np.ndarray) -> tuple[float, float]:
    """(translation metres, rotation radians) between two (4, 4) poses of one frame."""
    angle = Rotation.from_matrix(T_a[:3, :3].T @ T_b[:3, :3]).magnitude()
    return float(np.linalg.norm(T_a[:3, 3] - T_b[:3, 3])), float(angle)


def interpolate_poses(T_a: np.ndarray, T_b: np.ndarray, s: float | np.ndarray) -> np.ndarray:
    """Poses a fraction ``s`` (scalar, or (n,) in [0, 1]) of the way from ``T_a`` to ``T_b`` (4, 4):
    translation linear, rotation by slerp. (4, 4) for a scalar ``s``, else (n, 4, 4)."""
    s_n = np.atleast_1d(np.asarray(s, dtype=np.float64))
    T = np.tile(np.eye(4), (s_n.size, 1, 1))
    T[:, :3, :3] = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([T_a[:3, :3], T_b[:3, :3]])))(
        s_n
    ).as_matrix()
    T[:, :3, 3] = (1.0 - s_n)[:, None] * T_a[:3, 3] + s_n[:, None] * T_b[:3, 3]
    return T[0] if np.ndim(s) == 0 else T


class HasMatrix(Protocol):
    def matrix(self) -> np.ndarray: ...


class PoseTimeline:
    """Poses of one frame stamped in ns, sorted by stamp (late ones sorted in), the oldest dropped
    beyond ``maxlen``: (4, 4) matrices, or messages with ``matrix()`` converted when looked up. Not
    thread-safe; ``name`` names the poses in errors."""

    def __init__(self, maxlen: int = 100_000, name: str = "flange pose") -> None:
        self.stamps_ns: list[int] = []
        self.poses: list[np.ndarray | HasMatrix] = []
        self.maxlen, self.name = maxlen, name

    def __len__(self) -> int:
        return len(self.stamps_ns)

    def clear(self) -> None:
        self.stamps_ns.clear()
        self.poses.clear()

    def add(self, stamp_ns: int, pose: np.ndarray | HasMatrix) -> None:
        k = bisect_right(self.stamps_ns, stamp_ns)
        self.stamps_ns.insert(k, int(stamp_ns))
        self.poses.insert(k, pose)
        if len(self.stamps_ns) > self.maxlen:
            del self.stamps_ns[0], self.poses[0]

    def matrix(self, i: int) -> np.ndarray:
        """(4, 4) the ``i``-th pose (in stamp order)."""
        pose = self.poses[i]
        return pose if isinstance(pose, np.ndarray) else pose.matrix()

    def at(self, stamp_ns: int, tolerance_ns: int, max_gap_ns: int) -> np.ndarray:
        """(4, 4) pose at ``stamp_ns``: the one stamped then, else interpolated between the two around
        it (:func:`interpolate_poses`) when at most ``max_gap_ns`` apart, else the nearest within
        ``tolerance_ns``. Raises LookupError saying how far the nearest is."""
        s = self.stamps_ns
        if not s:
            raise LookupError(f"no {self.name} received yet")
        k = bisect_left(s, stamp_ns)
        if k < len(s) and s[k] == stamp_ns:
            return self.matrix(k)
        if 0 < k < len(s) and s[k] - s[k - 1] <= max_gap_ns:
            return interpolate_poses(
                self.matrix(k - 1), self.matrix(k), (stamp_ns - s[k - 1]) / (s[k] - s[k - 1])
            )
        near = k - 1 if k == len(s) or (k > 0 and stamp_ns - s[k - 1] <= s[k] - stamp_ns) else k
        gap = abs(s[near] - stamp_ns)
        if gap > tolerance_ns:
            raise LookupError(
                f"nearest {self.name} is {gap / 1e6:.1f} ms from {stamp_ns} ns (tolerance {tolerance_ns / 1e6:.1f} ms)"
            )
        return self.matrix(near)
