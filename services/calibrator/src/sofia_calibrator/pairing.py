"""Pair blob observations with flange poses by stamp: interpolation between poses (linear
translation, slerp rotation), a stamp tolerance, and rejection of samples taken while moving."""

from __future__ import annotations

import bisect
from dataclasses import dataclass

import numpy as np
from sofia_schemas.transforms import interpolate_poses, rotation_angle

from .errors import CalibrationError


class NotPaired(CalibrationError):  # noqa: N818 - named as in STYLE.md
    def __init__(self, stamp_ns: int, reason: str) -> None:
        super().__init__(f"blob at {stamp_ns} ns not paired: {reason}")
        self.reason = reason


@dataclass
class PairingOptions:
    tolerance_ns: int = 50_000_000  # nearest pose accepted this close when not bracketed
    max_gap_ns: int = 500_000_000  # bracketing poses further apart than this are not interpolated
    still_window_ns: int = 150_000_000  # the flange must be still this long either side
    still_translation_m: float = 0.001
    still_rotation_deg: float = 0.3


class PoseBuffer:
    """Stamped flange poses T_base_flange, sorted by stamp (int ns)."""

    def __init__(self, max_len: int = 100_000) -> None:
        self.stamps_ns: list[int] = []
        self.poses: list[np.ndarray] = []
        self.max_len = max_len

    def __len__(self) -> int:
        return len(self.stamps_ns)

    def add(self, stamp_ns: int, T_base_flange: np.ndarray) -> None:
        k = bisect.bisect_right(self.stamps_ns, stamp_ns)
        self.stamps_ns.insert(k, int(stamp_ns))
        self.poses.insert(k, np.asarray(T_base_flange, dtype=np.float64))
        if len(self.stamps_ns) > self.max_len:
            del self.stamps_ns[0], self.poses[0]

    def pose_at(self, stamp_ns: int, opts: PairingOptions) -> np.ndarray:
        """(4, 4) T_base_flange at ``stamp_ns``: interpolated between bracketing poses, or the nearest
        within the tolerance; NotPaired otherwise."""
        if not self.stamps_ns:
            raise NotPaired(stamp_ns, "no flange pose received yet")
        k = bisect.bisect_left(self.stamps_ns, stamp_ns)
        if k < len(self.stamps_ns) and self.stamps_ns[k] == stamp_ns:
            return self.poses[k]
        if 0 < k < len(self.stamps_ns):
            t0, t1 = self.stamps_ns[k - 1], self.stamps_ns[k]
            if t1 - t0 <= opts.max_gap_ns:
                return interpolate_poses(self.poses[k - 1], self.poses[k], (stamp_ns - t0) / (t1 - t0))
        near = min((i for i in (k - 1, k) if 0 <= i < len(self.stamps_ns)),
                   key=lambda i: abs(self.stamps_ns[i] - stamp_ns))  # fmt: skip
        gap = abs(self.stamps_ns[near] - stamp_ns)
        if gap <= opts.tolerance_ns:
            return self.poses[near]
        raise NotPaired(stamp_ns, f"nearest flange pose is {gap / 1e6:.1f} ms away (tolerance "
                                  f"{opts.tolerance_ns / 1e6:.1f} ms)")  # fmt: skip

    def pair(self, stamp_ns: int, opts: PairingOptions) -> np.ndarray:
        """T_base_flange for a blob at ``stamp_ns`` taken while still (the flange did not move within
        ``still_window_ns`` of it); NotPaired otherwise."""
        T_pair = self.pose_at(stamp_ns, opts)
        lo = bisect.bisect_left(self.stamps_ns, stamp_ns - opts.still_window_ns)
        hi = bisect.bisect_right(self.stamps_ns, stamp_ns + opts.still_window_ns)
        if hi - lo < 1:
            return T_pair
        T = np.stack([T_pair, *self.poses[lo:hi]])
        dt = float(np.max(np.linalg.norm(T[:, :3, 3] - T[0, :3, 3], axis=1)))
        dr = float(np.degrees(np.max(rotation_angle(np.einsum("ji,njk->nik", T[0, :3, :3], T[:, :3, :3])))))
        if dt > opts.still_translation_m or dr > opts.still_rotation_deg:
            raise NotPaired(
                stamp_ns,
                f"the flange was moving ({dt * 1e3:.1f} mm, {dr:.2f} deg within "
                f"{opts.still_window_ns / 1e6:.0f} ms)",
            )
        return T_pair
