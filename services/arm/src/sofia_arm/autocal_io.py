"""What the autonomous calibration sees and whom it tells: camera frames, the calibrator, progress.

Two implementations of each: over Zenoh (the camera key, the calibrator's queryables, the
progress key) for the service, and in-process (the calibrator library) for benchmarks.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import zenoh
from sofia_runtime.client import QueryError, ask
from sofia_schemas import pointcloud
from sofia_schemas.keys import ENCODING_JSON, Keys
from sofia_schemas.messages import ArmPhase, CalibrationResult, CalibrationSample
from sofia_schemas.messages.calibration import CalibrationSamples, CalibrationSolveOptions
from sofia_schemas.transforms import matrix_to_quat_xyzw


@dataclass
class Frame:
    """One organized camera frame. points_cam: (H, W, 3) float, camera optical frame, metres, NaN
    where missing; rgb: (H, W, 3) uint8 or None."""

    stamp_ns: int
    points_cam: np.ndarray
    rgb: np.ndarray | None


class Eye(Protocol):
    def frame_after(self, stamp_ns: int, timeout_s: float) -> Frame | None:
        """The first frame stamped at or after ``stamp_ns`` (None when none came in time)."""
        ...


class CalibratorLink(Protocol):
    def reset(self) -> None: ...

    def add(self, stamp_ns: int, p_cam: np.ndarray, T_base_flange: np.ndarray, confidence: float) -> None: ...

    def solve(self) -> CalibrationResult: ...


def sample(
    stamp_ns: int, p_cam: np.ndarray, T_base_flange: np.ndarray, confidence: float
) -> CalibrationSample:
    """The calibrator's sample of a blob ``p_cam`` (3,) (camera frame, m) seen at ``T_base_flange``."""
    q = matrix_to_quat_xyzw(T_base_flange[:3, :3])
    return CalibrationSample(
        stamp_ns=stamp_ns, p_cam=tuple(float(v) for v in p_cam),  # type: ignore[arg-type]
        translation=tuple(float(v) for v in T_base_flange[:3, 3]),  # type: ignore[arg-type]
        rotation_xyzw=tuple(float(v) for v in q), confidence=float(np.clip(confidence, 0.0, 1.0)),  # type: ignore[arg-type]
    )  # fmt: skip


class BusEye:
    """Organized clouds from ``sofia/{robot}/camera/points`` (the newest one kept, decoded on use)."""

    def __init__(self, session: zenoh.Session, keys: Keys) -> None:
        self._cond = threading.Condition()
        self._latest: tuple[int, bytes] | None = None
        self.bad = 0
        self._sub = session.declare_subscriber(keys.camera_points, self._on_cloud)

    def _on_cloud(self, s: zenoh.Sample) -> None:
        payload = s.payload.to_bytes()
        try:
            stamp = pointcloud.decode(payload).stamp_ns
        except Exception:  # a malformed cloud is counted, not fatal
            self.bad += 1
            return
        with self._cond:
            self._latest = (stamp, payload)
            self._cond.notify_all()

    def frame_after(self, stamp_ns: int, timeout_s: float) -> Frame | None:
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while self._latest is None or self._latest[0] < stamp_ns:
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self._cond.wait(left)
            stamp, payload = self._latest
        cloud = pointcloud.decode(payload)
        shape = (cloud.height, cloud.width, 3)
        rgb = cloud.rgb()
        return Frame(stamp, np.asarray(cloud.xyz(), dtype=np.float64).reshape(shape),
                     None if rgb is None else np.asarray(rgb).reshape(shape))  # fmt: skip

    def close(self) -> None:
        self._sub.undeclare()


class BusCalibrator:
    """The calibrator service through its queryables (``reset``, ``add``, ``solve``); ``setup``
    (sent with the reset and each solve, kept by the service) picks ``T_flange_cam`` or
    ``T_base_cam``."""

    def __init__(self, session: zenoh.Session, keys: Keys, timeout_s: float = 10.0,
                 setup: str = "eye-in-hand") -> None:  # fmt: skip
        self.session, self.keys, self.timeout_s = session, keys, timeout_s
        self.options = CalibrationSolveOptions(setup=setup).model_dump_json()  # type: ignore[arg-type]

    def reset(self) -> None:
        # the set-up goes with the reset: the service's own solves in between use it too
        ask(self.session, self.keys.calibrator_op("reset"), CalibrationSamples, self.options, self.timeout_s)

    def add(self, stamp_ns: int, p_cam: np.ndarray, T_base_flange: np.ndarray, confidence: float) -> None:
        payload = sample(stamp_ns, p_cam, T_base_flange, confidence).model_dump_json()
        ask(self.session, self.keys.calibrator_op("add"), CalibrationSamples, payload, self.timeout_s)

    def solve(self) -> CalibrationResult:
        return ask(
            self.session, self.keys.calibrator_op("solve"), CalibrationResult, self.options, self.timeout_s
        )


class LocalCalibrator:
    """The calibrator library in this process (benchmarks and planning studies)."""

    def __init__(self, setup: str = "eye-in-hand") -> None:
        self.setup = setup
        self.p_cam: list[np.ndarray] = []
        self.T_base_flange: list[np.ndarray] = []
        self.confidence: list[float] = []

    def reset(self) -> None:
        self.p_cam, self.T_base_flange, self.confidence = [], [], []

    def add(self, stamp_ns: int, p_cam: np.ndarray, T_base_flange: np.ndarray, confidence: float) -> None:
        self.p_cam.append(np.asarray(p_cam, dtype=np.float64))
        self.T_base_flange.append(np.asarray(T_base_flange, dtype=np.float64))
        self.confidence.append(confidence)

    def solve(self) -> CalibrationResult:
        from sofia_calibrator import to_message
        from sofia_calibrator.eye_to_hand import calibrate_setup
        from sofia_calibrator.online import MIN_CONFIDENCE

        p = np.array(self.p_cam)
        conf = np.clip(self.confidence, MIN_CONFIDENCE, 1.0)  # as the service: default noise and correction
        try:
            cal = calibrate_setup(
                p, np.array(self.T_base_flange), self.setup, confidence=conf, leave_one_out=False
            )
        except Exception as e:  # the service answers an error reply: the same here
            raise QueryError(f"calibrate: {type(e).__name__}: {e}") from e
        return to_message(cal)


class Progress:
    """Steps published on ``sofia/{robot}/arm/progress`` (JSON ArmPhase) and kept for the result."""

    def __init__(self, session: zenoh.Session | None, keys: Keys | None) -> None:
        self.phases: list[ArmPhase] = []
        self._pub = None if session is None or keys is None else session.declare_publisher(keys.arm_progress)

    def add(self, name: str, status: str, reason: str = "", duration_s: float = 0.0) -> ArmPhase:
        phase = ArmPhase(name=name, status=status, reason=reason, duration_s=round(duration_s, 3))  # type: ignore[arg-type]
        self.phases.append(phase)
        if self._pub is not None:
            self._pub.put(phase.model_dump_json(), encoding=ENCODING_JSON)
        return phase

    def close(self) -> None:
        if self._pub is not None:
            self._pub.undeclare()
