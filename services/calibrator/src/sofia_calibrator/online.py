"""The online calibrator's state: stored samples, blob/pose pairing, and the current solution."""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np
from sofia_schemas import rosmsg
from sofia_schemas.messages import CalibrationResult, now_ns
from sofia_schemas.messages.calibration import (
    CalibrationSample,
    CalibrationSolveOptions,
)
from sofia_schemas.transforms import make_transform, matrix_to_quat_xyzw

from .calibrate import calibrate
from .errors import InputMismatch
from .formats import to_message
from .noise import camera_sigma
from .pairing import NotPaired, PairingOptions, PoseBuffer
from .store import SampleStore

log = logging.getLogger("sofia.calibrator")
PENDING_TIMEOUT_S = 2.0


@dataclass
class Calibrator:
    """The service's state, touched only by the worker thread."""

    store: SampleStore
    pairing: PairingOptions = field(default_factory=PairingOptions)
    min_samples: int = 3
    poses: PoseBuffer = field(default_factory=PoseBuffer)
    pending: list[tuple[int, np.ndarray, float, float]] = field(default_factory=list)  # stamp, p, conf, t
    result: CalibrationResult | None = None
    options: CalibrationSolveOptions = field(default_factory=CalibrationSolveOptions)
    last_error: str = ""

    def on_pose(self, payload: bytes) -> None:
        pose = rosmsg.decode_flange_pose(payload)
        self.poses.add(pose.stamp_ns, pose.matrix())

    def on_blob(self, stamp_ns: int, p_cam: np.ndarray, confidence: float) -> None:
        self.pending.append((stamp_ns, p_cam, confidence, time.monotonic()))

    def pair_pending(self) -> list[CalibrationSample]:
        """Pair the blobs whose flange poses (up to the still window after them) have arrived."""
        added, keep = [], []
        latest = self.poses.latest_ns
        for stamp_ns, p_cam, conf, t_in in self.pending:
            ready = latest is not None and latest >= stamp_ns + self.pairing.still_window_ns
            if not ready and time.monotonic() - t_in < PENDING_TIMEOUT_S:
                keep.append((stamp_ns, p_cam, conf, t_in))
                continue
            try:
                T = self.poses.pair(stamp_ns, self.pairing)
            except NotPaired as e:
                log.info("sample skipped: %s", e)
                continue
            added.append(self.store.add(_sample(stamp_ns, p_cam, T, conf)))
            log.info("sample %d added (%d samples)", added[-1].sample_id, len(self.store.samples))
        self.pending = keep
        return added

    def solve(self, options: CalibrationSolveOptions | None = None) -> CalibrationResult:
        opts = options or self.options
        p, T, ids = self.store.arrays()
        guess = (
            None if opts.guess is None else make_transform(np.array(opts.guess[:3]), np.array(opts.guess[3:]))
        )
        if opts.noise not in ("depth", "uniform"):
            raise InputMismatch(f"noise must be 'depth' or 'uniform', got {opts.noise!r}")
        sigma = camera_sigma(p) if opts.noise == "depth" else np.full_like(p, 1e-3)
        conf = np.array([s.confidence for s in self.store.ordered()])
        sigma = sigma / np.clip(conf, 0.05, 1.0)[:, None]  # a less confident blob weighs less
        cal = calibrate(p, T, guess=guess, sigma=sigma, loss=opts.loss, exclude_outliers=opts.exclude_outliers,
                        leave_one_out=len(p) <= 60)  # fmt: skip
        self.result = to_message(cal, now_ns(), ids)
        self.result = self.result.model_copy(
            update={"inliers": [ids[i] for i in cal.inliers], "outliers": [ids[i] for i in cal.outliers]}
        )
        return self.result


def _sample(stamp_ns: int, p_cam: np.ndarray, T: np.ndarray, confidence: float) -> CalibrationSample:
    q = matrix_to_quat_xyzw(T[:3, :3])
    return CalibrationSample(
        stamp_ns=stamp_ns, p_cam=tuple(map(float, p_cam)), translation=tuple(map(float, T[:3, 3])),  # type: ignore[arg-type]
        rotation_xyzw=tuple(map(float, q)), confidence=confidence,  # type: ignore[arg-type]
    )  # fmt: skip
