"""What a calibration sample must satisfy before the calibrator accepts (or replays) it."""

from __future__ import annotations

import math

from sofia_schemas.messages.calibration import CalibrationSample
from sofia_schemas.transforms import QUAT_NORM_TOL

from .errors import ImplausibleSample

FLANGE_MAX_M = 5.0  # |T_base_flange translation|: the Panda reaches 0.855 m; 5 m allows other arms
BLOB_MAX_M = 10.0  # |p_cam|: the D435 sees depth to about 10 m
STAMP_MAX_NS = 2**63 - 1  # stamps are int64 nanoseconds, as in ROS and MCAP


def check_sample(sample: CalibrationSample) -> None:
    """Raise :class:`ImplausibleSample` naming every reason ``sample`` cannot be a real observation.

    Checks: every value finite; ``rotation_xyzw`` a unit quaternion (x y z w) within
    ``QUAT_NORM_TOL``; the flange within ``FLANGE_MAX_M`` of the base; the blob (camera optical
    frame) in front of the camera (z > 0) and within ``BLOB_MAX_M`` of it; ``0 <= stamp_ns < 2**63``.
    """
    reasons = []
    named = {"p_cam": sample.p_cam, "translation": sample.translation, "rotation_xyzw": sample.rotation_xyzw}
    bad = [name for name, v in named.items() if not all(math.isfinite(x) for x in v)]
    if bad:
        reasons.append(f"non-finite values in {', '.join(bad)}")
    if "rotation_xyzw" not in bad:
        norm = math.hypot(*sample.rotation_xyzw)
        if abs(norm - 1.0) > QUAT_NORM_TOL:
            reasons.append(
                f"rotation_xyzw {list(sample.rotation_xyzw)} has norm {norm:.6g}, not 1 "
                f"(within {QUAT_NORM_TOL}): a unit quaternion x y z w is needed"
            )
    if "translation" not in bad and (d := math.hypot(*sample.translation)) > FLANGE_MAX_M:
        reasons.append(f"flange translation is {d:.4g} m from the base, more than {FLANGE_MAX_M} m")
    if "p_cam" not in bad and (d := math.hypot(*sample.p_cam)) > BLOB_MAX_M:
        reasons.append(f"blob p_cam is {d:.4g} m from the camera, more than {BLOB_MAX_M} m")
    if "p_cam" not in bad and sample.p_cam[2] <= 0.0:
        reasons.append(
            f"blob p_cam z = {sample.p_cam[2]:.4g} m is not in front of the camera (optical frame: +z)"
        )
    if not 0 <= sample.stamp_ns <= STAMP_MAX_NS:
        stamp = str(sample.stamp_ns)
        shown = stamp if len(stamp) <= 24 else f"{stamp[:12]}... ({len(stamp)} digits)"
        reasons.append(f"stamp_ns {shown} is outside 0 .. 2**63-1 ns")
    if not 0.0 <= sample.confidence <= 1.0 or not math.isfinite(sample.confidence):
        reasons.append(f"confidence {sample.confidence} is outside [0, 1]")
    if reasons:
        raise ImplausibleSample(sample.sample_id, reasons)
