"""The online calibrator's state: stored samples, blob/pose pairing, and the current solution."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from sofia_runtime.stamps import StampCheck
from sofia_schemas import rosmsg
from sofia_schemas.messages import CalibrationResult, now_ns
from sofia_schemas.messages.calibration import (
    CalibrationSample,
    CalibrationSolveOptions,
)
from sofia_schemas.transforms import make_transform, matrix_to_quat_xyzw

from .errors import CalibrationError
from .eye_to_hand import BASE_FRAME, calibrate_setup
from .fitting.calibrate import CHILD_FRAME, PARENT_FRAME
from .formats import to_message
from .pairing import NotPaired, PairingOptions, PoseBuffer
from .samples.store import SampleStore

log = logging.getLogger("sofia.calibrator")
PENDING_TIMEOUT_S = 2.0
PENDING_MAX = 1000  # blobs waiting for their poses; beyond, the oldest is dropped (and counted)
MIN_CONFIDENCE = 0.05  # a blob's confidence below this weighs as this (0, which a sample may carry, too)


@dataclass
class Calibrator:
    """The service's state, touched only by the worker thread."""

    store: SampleStore
    pairing: PairingOptions = field(default_factory=PairingOptions)
    min_samples: int = 3
    parent_frame: str = PARENT_FRAME  # the frames the published T_flange_cam names
    child_frame: str = CHILD_FRAME
    poses: PoseBuffer = field(default_factory=PoseBuffer)
    pending: list[tuple[int, np.ndarray, float, float]] = field(default_factory=list)  # stamp, p, conf, t
    result: CalibrationResult | None = None
    options: CalibrationSolveOptions = field(default_factory=CalibrationSolveOptions)
    last_error: str = ""
    refused: int = 0  # paired samples refused: implausible, or the log could not store them
    dropped: int = 0  # blobs dropped from a full pending list
    stamps: StampCheck = field(default_factory=StampCheck)  # poses, blobs, samples stamped in the future
    # stamp_ns of samples -> better target centres for the solve (a ball's shared radius), if any
    centres: Callable[[list[int]], dict[int, np.ndarray]] | None = None

    def on_pose(self, payload: bytes) -> None:
        pose = rosmsg.decode_flange_pose(payload)
        self.poses.add(self.stamps.check("flange pose", pose.stamp_ns), pose.matrix())

    def on_blob(self, stamp_ns: int, p_cam: np.ndarray, confidence: float) -> None:
        self.stamps.check("blob", stamp_ns)
        if len(self.pending) >= PENDING_MAX:
            del self.pending[0]
            self.dropped += 1
        self.pending.append((stamp_ns, p_cam, confidence, time.monotonic()))

    def pair_pending(self) -> list[CalibrationSample]:
        """Pair the blobs whose flange poses (up to the still window after them) have arrived."""
        added, keep = [], []
        latest = self.poses.stamps_ns[-1] if self.poses.stamps_ns else None
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
            try:
                added.append(self.store.add(make_sample(stamp_ns, p_cam, T, conf)))
            except CalibrationError as e:  # implausible, or not durable: not stored, never acknowledged
                self.refused += 1
                log.warning("sample of blob %d refused: %s", stamp_ns, e)
                continue
            log.info("sample %d added (%d samples)", added[-1].sample_id, len(self.store.samples))
        self.pending = keep
        return added

    def solve(self, options: CalibrationSolveOptions | None = None) -> CalibrationResult:
        """``calibrate()`` of the stored samples as ``sofia calibrate`` runs it: noise model, camera
        correction, loss and outliers from ``options`` (default: the service's), a less confident blob
        weighing less. ``options.setup`` eye-to-hand solves ``T_base_cam`` (the stored flange poses
        inverted, :mod:`sofia_calibrator.eye_to_hand`)."""
        opts = options or self.options
        p, T, ids = self.store.arrays()
        samples = self.store.ordered()  # the rows of p and T
        better = self.centres([s.stamp_ns for s in samples]) if self.centres is not None else {}
        if better:  # the stored centres stay as measured; the solve takes these
            p = np.array([better.get(s.stamp_ns, row) for s, row in zip(samples, p, strict=True)])
        guess = (
            None if opts.guess is None else make_transform(np.array(opts.guess[:3]), np.array(opts.guess[3:]))
        )
        conf = np.clip([s.confidence for s in samples], MIN_CONFIDENCE, 1.0)
        parent = self.parent_frame  # eye-to-hand, T_base_cam: the base is the parent (unless configured)
        parent = BASE_FRAME if opts.setup == "eye-to-hand" and parent == PARENT_FRAME else parent
        cal = calibrate_setup(
            p, T, opts.setup, guess=guess, sigma=opts.noise, confidence=conf, loss=opts.loss,  # type: ignore[arg-type]
            exclude_outliers=opts.exclude_outliers, correction=opts.correction,
            depth_scale_prior=opts.depth_scale_prior, parent_frame=parent, child_frame=self.child_frame,
        )  # fmt: skip
        self.result = to_message(cal, now_ns(), ids)
        self.result = self.result.model_copy(
            update={"inliers": [ids[i] for i in cal.inliers], "outliers": [ids[i] for i in cal.outliers]}
        )
        return self.result


def make_sample(
    stamp_ns: int, p_cam: np.ndarray, T: np.ndarray, confidence: float = 1.0
) -> CalibrationSample:
    """A sample from a blob ``p_cam`` (3,) (camera optical frame, metres) and ``T_base_flange`` (4, 4)."""
    q = matrix_to_quat_xyzw(T[:3, :3])
    return CalibrationSample(
        stamp_ns=stamp_ns, p_cam=tuple(map(float, p_cam)), translation=tuple(map(float, T[:3, 3])),  # type: ignore[arg-type]
        rotation_xyzw=tuple(map(float, q)), confidence=confidence,  # type: ignore[arg-type]
    )  # fmt: skip
