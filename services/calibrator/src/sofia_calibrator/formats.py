"""The calibration as the lab needs it: bus message, JSON, YAML, ROS 1 and ROS 2 static transforms.

Every output names the direction: ``T_flange_cam`` (parent ``panda_link8`` = flange, child
``camera_color_optical_frame`` = the clouds' frame, :mod:`sofia_schemas.frames`) maps camera-frame
points into the flange frame; metres; quaternions x y z w.
"""

from __future__ import annotations

import numpy as np
from sofia_schemas.messages import CalibrationResult, now_ns
from sofia_schemas.messages.calibration import CalibrationSummary, CorrectionCandidate
from sofia_schemas.transforms import matrix_to_quat_xyzw

from .fitting.calibrate import CHILD_FRAME, PARENT_FRAME, Calibration
from .fitting.fit import Fit


def _f(v: float) -> str:
    return f"{float(v):.6f}"


def _pose7(T: np.ndarray) -> list[float]:
    """x y z qx qy qz qw of a (4, 4) transform."""
    return [*T[:3, 3], *matrix_to_quat_xyzw(T[:3, :3])]


def ros1_static_transform(
    T_flange_cam: np.ndarray, parent: str = PARENT_FRAME, child: str = CHILD_FRAME
) -> str:
    """The lab launch file's line: ``static_transform_publisher x y z qx qy qz qw parent child 100``."""
    args = " ".join(_f(v) for v in _pose7(T_flange_cam))
    return (
        f'<node pkg="tf" type="static_transform_publisher" name="camera_optical_broadcaster" '
        f'args="{args} {parent} {child} 100" />'
    )


def ros2_static_transform(
    T_flange_cam: np.ndarray, parent: str = PARENT_FRAME, child: str = CHILD_FRAME
) -> str:
    """``ros2 run tf2_ros static_transform_publisher --x .. --qw .. --frame-id parent --child-frame-id child``."""
    names = ("x", "y", "z", "qx", "qy", "qz", "qw")
    args = " ".join(f"--{k} {_f(v)}" for k, v in zip(names, _pose7(T_flange_cam), strict=True))
    return f"ros2 run tf2_ros static_transform_publisher {args} --frame-id {parent} --child-frame-id {child}"


def _vec(v: np.ndarray) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def _summary(fit: Fit) -> CalibrationSummary:
    return CalibrationSummary(
        samples=fit.samples, matrix=fit.T_flange_cam.tolist(), translation=_vec(fit.translation),
        quaternion_xyzw=tuple(float(v) for v in fit.quaternion_xyzw),  # type: ignore[arg-type]
        target_base=_vec(fit.p_base), spread_mm=_vec(fit.spread_mm), passes=fit.passes,
        residuals_mm=fit.residuals_mm.tolist(), dissipation_after=fit.dissipation_after,
    )  # fmt: skip


def _candidates(cal: Calibration) -> list[CorrectionCandidate]:
    return [CorrectionCandidate(
        model=c.model, n_params=c.n_params, chi2=c.chi2, aic=c.aic, p_value=c.p_value,  # type: ignore[arg-type]
        depth_scale=1.0 + float(c.beta[0]) if len(c.beta) else 1.0, chosen=c.model == cal.correction.model,
        depth_scale_sigma=None if c.beta_sigma is None else float(c.beta_sigma[0]),
    ) for c in cal.candidates]  # fmt: skip


def to_message(
    cal: Calibration, stamp_ns: int | None = None, sample_ids: list[int] | None = None
) -> CalibrationResult:
    """The :class:`CalibrationResult` bus message of a calibration, in the calibration's frames."""
    T, parent, child = cal.T_flange_cam, cal.parent_frame, cal.child_frame
    return CalibrationResult(
        stamp_ns=now_ns() if stamp_ns is None else stamp_ns,
        parent_frame=parent, child_frame=child, matrix=T.tolist(),
        translation=_vec(cal.translation),
        quaternion_xyzw=tuple(float(v) for v in cal.quaternion_xyzw),  # type: ignore[arg-type]
        rpy=_vec(cal.rpy), target_base=_vec(cal.p_base), spread_mm=_vec(cal.spread_mm),
        passes=cal.passes, n_samples=len(cal.p_cam), inliers=cal.inliers, outliers=cal.outliers,
        residuals_mm=cal.residuals_mm.tolist(), std_translation_mm=_vec(cal.std_translation_mm),
        std_rotation_deg=_vec(cal.std_rotation_deg), dissipation_before=cal.dissipation_before,
        dissipation_after=cal.dissipation_after, warnings=cal.warnings,
        ros1_static_transform=ros1_static_transform(T, parent, child),
        ros2_static_transform=ros2_static_transform(T, parent, child),
        leave_one_out_mm=cal.leave_one_out_mm.tolist(), noise_scale=cal.noise_scale,
        sample_ids=sample_ids or [],
        with_all_samples=_summary(cal.with_all_samples) if cal.with_all_samples else None,
        without_outliers=_summary(cal.without_outliers) if cal.without_outliers else None,
        camera_correction=cal.correction, correction_models=_candidates(cal),
        correction_reason=cal.correction_reason, noise_mm=cal.noise_mm if np.isfinite(cal.noise_mm) else None,
        covariance=cal.covariance6.tolist(), criterion_advice=cal.criterion_advice,
    )  # fmt: skip


def to_yaml(result: CalibrationResult) -> str:
    """A YAML document of the calibration (hand-written: flat keys, lists inline)."""

    def fl(v: object) -> str:
        if isinstance(v, list | tuple):
            return "[" + ", ".join(fl(x) for x in v) + "]"
        if isinstance(v, float):
            text = f"{v:.9g}" if abs(v) < 1e-4 and v != 0.0 else repr(round(v, 9))
            mant, e, exp = text.partition("e")
            return f"{mant}{'' if '.' in mant else '.0'}e{exp}" if e else text  # YAML 1.1 floats need a dot
        return str(v)

    lines = [
        "# T_flange_cam: maps points in the camera optical frame into the flange frame (metres).",
        f"parent_frame: {result.parent_frame}",
        f"child_frame: {result.child_frame}",
        f"translation: {fl(result.translation)}  # x y z, metres",
        f"quaternion_xyzw: {fl(result.quaternion_xyzw)}",
        f"rpy: {fl(result.rpy)}  # roll pitch yaw, radians, extrinsic x-y-z",
        "matrix:",
        *[f"  - {fl(row)}" for row in result.matrix],
        f"target_base: {fl(result.target_base)}",
        f"spread_mm: {fl(result.spread_mm)}",
        f"passes: {str(result.passes).lower()}",
        f"std_translation_mm: {fl(result.std_translation_mm)}",
        f"std_rotation_deg: {fl(result.std_rotation_deg)}",
        "# camera_correction: apply to measured camera points before T_flange_cam",
        f"# {result.camera_correction.describe()}",
        "camera_correction:",
        f"  model: {result.camera_correction.model}",
        f"  depth_scale: {fl(result.camera_correction.depth_scale)}",
        f"  depth_scale_sigma: {fl(result.camera_correction.depth_scale_sigma) if result.camera_correction.depth_scale_sigma is not None else 'null'}",
        f"  depth_offset_m: {fl(result.camera_correction.depth_offset_m)}",
        f"correction_reason: {result.correction_reason!r}",
        f"noise_mm: {fl(result.noise_mm) if result.noise_mm is not None else 'null'}  # estimated 1-sigma per camera axis",
        "# covariance of T_flange_cam: tx ty tz (m, flange frame), rx ry rz (rad, about the flange axes)",
        "covariance:" if result.covariance else "covariance: []",
        *[f"  - {fl(row)}" for row in result.covariance],
        f"criterion_advice: {fl(result.criterion_advice)}",
        f"inliers: {fl(result.inliers)}",
        f"outliers: {fl(result.outliers)}",
        f"ros1_static_transform: '{result.ros1_static_transform}'",
        f"ros2_static_transform: '{result.ros2_static_transform}'",
        "warnings:",
        *[f"  - {w!r}" for w in result.warnings],
    ]
    if not result.warnings:
        lines[-1] = "warnings: []"
    return "\n".join(lines) + "\n"
