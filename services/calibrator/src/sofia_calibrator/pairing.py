"""Pair blob observations with flange poses by stamp: interpolation between poses (linear
translation, slerp rotation), a stamp tolerance, and rejection of samples taken while moving."""

from __future__ import annotations

from bisect import bisect_left, bisect_right
from dataclasses import dataclass

import numpy as np
from sofia_schemas.transforms import PoseTimeline, rotation_angle

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


class PoseBuffer(PoseTimeline):
    """Stamped flange poses T_base_flange (4, 4), sorted by stamp (int ns)."""

    def pose_at(self, stamp_ns: int, opts: PairingOptions) -> np.ndarray:
        """(4, 4) T_base_flange at ``stamp_ns``: interpolated between bracketing poses, or the nearest
        within the tolerance; NotPaired otherwise."""
        try:
            return self.at(stamp_ns, opts.tolerance_ns, opts.max_gap_ns)
        except LookupError as e:
            raise NotPaired(stamp_ns, str(e)) from None

    def pair(self, stamp_ns: int, opts: PairingOptions) -> np.ndarray:
        """T_base_flange for a blob at ``stamp_ns`` taken while still (the flange did not move within
        ``still_window_ns`` of it); NotPaired otherwise."""
        T_pair = self.pose_at(stamp_ns, opts)
        lo = bisect_left(self.stamps_ns, stamp_ns - opts.still_window_ns)
        hi = bisect_right(self.stamps_ns, stamp_ns + opts.still_window_ns)
        if hi - lo < 1:
            return T_pair
        T = np.stack([T_pair, *(self.matrix(i) for i in range(lo, hi))])
        dt = float(np.max(np.linalg.norm(T[:, :3, 3] - T[0, :3, 3], axis=1)))
        dr = float(np.degrees(np.max(rotation_angle(np.einsum("ji,njk->nik", T[0, :3, :3], T[:, :3, :3])))))
        if dt > opts.still_translation_m or dr > opts.still_rotation_deg:
            raise NotPaired(
                stamp_ns,
                f"the flange was moving ({dt * 1e3:.1f} mm, {dr:.2f} deg within "
                f"{opts.still_window_ns / 1e6:.0f} ms)",
            )
        return T_pair
