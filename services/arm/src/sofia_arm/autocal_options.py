"""The ``calibrate`` command's options (its ``calibrate`` dict) and its :class:`ArmResult`."""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
from sofia_schemas.messages import ArmResult, CalibrationResult
from sofia_schemas.transforms import matrix_to_quat_xyzw

from .autocal_io import Progress
from .motion import ArmMotion

SETUPS = ("eye-in-hand", "eye-to-hand")
TARGETS = ("blob", "ball")  # eye-in-hand: the blob or a ball on the table; eye-to-hand: a ball
EYE_TO_HAND_DISTANCE_M = (0.45, 0.9)  # the ball's distance from a fixed camera (default)


@dataclass
class Outcome:
    """What a run did: its result, samples taken, poses visited and why it stopped."""

    result: CalibrationResult | None
    poses: int  # samples taken
    visits: int  # poses visited for samples (failed ones included)
    T_base_flange: list[np.ndarray] = field(default_factory=list)
    stop_reason: str = ""
    # (3,) translation 1-sigma, mm (flange axes eye-in-hand, base axes eye-to-hand): the stop rule's
    # (:meth:`~sofia_arm.autocal.Autocal.sigma_mm`), the calibrator's reported one never below the
    # noise model's; None without a result
    sigma_translation_mm: np.ndarray | None = None


@dataclass
class AutocalOptions:
    """Options of ``calibrate`` (the command's ``calibrate`` dict, every key optional).

    setup: eye-in-hand (the camera on the flange, the blob on the table) or eye-to-hand (a fixed
    camera, a ball on the flange). blob: rough target position (base frame eye-in-hand, flange frame
    eye-to-hand, m); guess: T_flange_cam (eye-to-hand: T_base_cam) as x y z qx qy qz qw; without
    either, both are found from the start pose (eye-in-hand: the table seen from flange tilts, the
    blob seen in those frames; eye-to-hand: the ball seen while the flange moves and turns a
    little). target: blob (default eye-in-hand) or ball (a coloured ball on the table eye-in-hand,
    on the flange eye-to-hand, where it is the only one). ball_radius: the ball's radius (m; None:
    fitted). distance_m: of the target from the camera (eye-to-hand default 0.45-0.9).
    """

    setup: str = "eye-in-hand"
    target: str = "blob"
    ball_radius: float | None = None

    blob: tuple[float, float, float] | None = None
    guess: tuple[float, ...] | None = None
    target_sigma_mm: float = 1.0
    max_poses: int = 20
    min_poses: int = 6
    distance_m: tuple[float, float] = (0.3, 0.6)
    max_tilt_deg: float = 40.0
    margin_px: float = 40.0
    speed: float = 0.2
    frame_timeout_s: float = 15.0
    max_failures: int = 4
    return_to_start: bool = True

    @classmethod
    def from_dict(cls, d: dict[str, Any], speed: float | None = None) -> AutocalOptions:
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ValueError(f"unknown calibrate option(s) {unknown}; known: {sorted(known)}")
        opts = cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()})  # type: ignore[arg-type]
        if speed is not None and "speed" not in d:
            opts.speed = speed
        if opts.setup not in SETUPS:
            raise ValueError(f"setup must be one of {list(SETUPS)}, got {opts.setup!r}")
        if opts.target not in TARGETS:
            raise ValueError(f"target must be one of {list(TARGETS)}, got {opts.target!r}")
        if opts.setup == "eye-to-hand" and "target" not in d:
            opts.target = "ball"
        if opts.setup == "eye-to-hand" and opts.target != "ball":
            raise ValueError(f"eye-to-hand calibrates with a ball on the flange, got target {opts.target!r}")
        if opts.setup == "eye-to-hand" and "distance_m" not in d:
            opts.distance_m = EYE_TO_HAND_DISTANCE_M
        if opts.ball_radius is not None and not 0.005 <= opts.ball_radius <= 0.1:
            raise ValueError(f"ball_radius must be within [0.005, 0.1] m, got {opts.ball_radius}")
        if opts.blob is not None and (len(opts.blob) != 3 or not np.all(np.isfinite(opts.blob))):
            raise ValueError(f"blob must be 3 finite numbers (x y z, m), got {opts.blob}")
        if opts.guess is not None and len(opts.guess) != 7:
            raise ValueError(f"guess must be x y z qx qy qz qw, got {opts.guess}")
        if not 0.05 <= opts.target_sigma_mm <= 50 or not 3 <= opts.min_poses <= opts.max_poses <= 200:
            raise ValueError(f"need 0.05 <= target_sigma_mm <= 50 (got {opts.target_sigma_mm}) and "
                             f"3 <= min_poses <= max_poses <= 200 (got {opts.min_poses}, {opts.max_poses})")  # fmt: skip
        lo, hi = opts.distance_m
        if not 0.2 <= lo < hi <= 1.0:
            raise ValueError(f"distance_m must satisfy 0.2 <= lo < hi <= 1.0 m, got {opts.distance_m}")
        return opts


def to_arm_result(arm: ArmMotion, outcome: Outcome | None, progress: Progress, duration_s: float,
                  error: str) -> ArmResult:  # fmt: skip
    """The command's :class:`ArmResult`: ``details`` holds the calibration result, the samples and
    visits used, why it stopped, the translation 1-sigma of the stop rule (``sigma_translation_mm``,
    flange axes, mm: the result's own ``std_translation_mm`` is the calibrator's, overconfident with
    the few samples of a planned run) and the launch-file line."""
    T = arm.T_base_flange()
    r = None if outcome is None else outcome.result
    ok = not error and r is not None and r.passes
    reason = error or ("no result" if r is None else outcome.stop_reason if outcome else "")
    details: dict[str, Any] = (
        {}
        if outcome is None
        else {"samples": outcome.poses, "visits": outcome.visits, "stop_reason": outcome.stop_reason}
    )
    if outcome is not None and outcome.sigma_translation_mm is not None:
        details["sigma_translation_mm"] = [round(float(v), 4) for v in outcome.sigma_translation_mm]
    if r is not None:
        details.update(result=r.model_dump(mode="json"), ros1_static_transform=r.ros1_static_transform)
    return ArmResult(
        ok=ok, command="calibrate", status="done" if ok else "failed", reason=reason,
        q=tuple(float(v) for v in arm.q()), position=tuple(float(v) for v in T[:3, 3]),  # type: ignore[arg-type]
        quaternion_xyzw=tuple(float(v) for v in matrix_to_quat_xyzw(T[:3, :3])),  # type: ignore[arg-type]
        duration_s=round(duration_s, 3), phases=progress.phases, details=details,
    )  # fmt: skip
