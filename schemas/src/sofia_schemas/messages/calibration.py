"""Calibration samples and results."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, ValidationError

from ..files import FileContentError, load_json_or_yaml
from ..frames import CAMERA_FRAME, FLANGE_FRAME
from .base import Finite, Message, Quat, Vec3

CorrectionModel = Literal["rigid", "depth_scale", "ray_scale", "depth_scale_offset"]
# Zenoh attachment of a camera-frame cloud whose producer already applied the calibration's
# CameraCorrection: consumers (the detector) must then not apply it again.
CORRECTION_APPLIED_ATTACHMENT = b"sofia.camera_correction=applied"


def correction_applied(attachment: bytes | None) -> bool:
    """Whether a cloud's Zenoh attachment says its producer already applied the camera correction."""
    return attachment is not None and bytes(attachment).startswith(CORRECTION_APPLIED_ATTACHMENT)


class CameraCorrection(Message):
    """Correction of the camera's measured points chosen by the calibration (identity by default).

    ``rigid``: none. ``depth_scale``: the camera-frame z is multiplied by ``depth_scale`` (x and y
    stay). ``ray_scale``: the whole point, i.e. its distance along the viewing ray, is multiplied
    by ``depth_scale``. ``depth_scale_offset``: z becomes ``depth_scale * z + depth_offset_m``.
    A depth scale of 0.95 means the camera's depth reads 5.3 % long (1 / 0.95 - 1).
    """

    model: CorrectionModel = "rigid"
    depth_scale: Finite = Field(1.0, gt=0.0)
    depth_scale_sigma: Finite | None = None  # 1-sigma of depth_scale
    depth_offset_m: Finite = 0.0

    @property
    def is_identity(self) -> bool:
        return self.model == "rigid" or (self.depth_scale == 1.0 and self.depth_offset_m == 0.0)

    def describe(self) -> str:
        """One line saying what the correction means for the user."""
        if self.model == "rigid":
            return "camera correction: none (rigid model): the camera's depth agrees with the robot"
        s = self.depth_scale
        pct = 100.0 * (1.0 / s - 1.0)
        what = "range along each ray" if self.model == "ray_scale" else "depth (camera z)"
        sig = f" +- {self.depth_scale_sigma:.4f}" if self.depth_scale_sigma is not None else ""
        off = f", then {1e3 * self.depth_offset_m:+.1f} mm" if self.depth_offset_m else ""
        how = (
            f"set the D435 depth units to {s:.4f} x the present ones (0.001 -> {0.001 * s:.7f}), or"
            if self.model == "ray_scale"
            else "the D435 depth units would also scale x and y:"
        )
        return (
            f"camera correction: {self.model}, scale {s:.4f}{sig}{off}: the camera's {what} reads "
            f"{abs(pct):.1f} % {'long' if pct > 0 else 'short'}; multiply it by {s:.4f} ({how} let the "
            "camera service / detector apply camera_correction)"
        )

    def apply(self, points_cam: np.ndarray) -> np.ndarray:
        """Corrected points: (n, 3) (or (..., 3)) measured, camera optical frame, metres -> same
        shape, corrected. NaN passes through; the input is not modified."""
        p = np.asarray(points_cam, dtype=np.float64)
        if p.shape[-1:] != (3,):
            raise ValueError(f"points_cam must have shape (..., 3), got {p.shape}")
        if self.model == "rigid":
            return p.copy()
        if self.model == "ray_scale":
            return p * self.depth_scale
        out = p.copy()
        out[..., 2] = p[..., 2] * self.depth_scale
        if self.model == "depth_scale_offset":
            out[..., 2] += self.depth_offset_m
        return out


class CalibrationSample(Message):
    """One blob observation paired with the flange pose at its stamp."""

    stamp_ns: int
    p_cam: Vec3  # blob, camera optical frame, metres
    translation: Vec3  # T_base_flange translation, metres
    rotation_xyzw: Quat  # T_base_flange rotation, x y z w
    confidence: float = Field(1.0, ge=0.0, le=1.0)
    sample_id: int | None = None


class CorrectionCandidate(Message):
    """One camera-correction model the calibration tried (fitted jointly with T_flange_cam)."""

    model: CorrectionModel
    n_params: int  # unknowns, T_flange_cam and the blob included
    chi2: float  # sum of squared residuals in units of the nominal noise
    aic: float  # n_obs log(chi2 / n_obs) + 2 n_params (relative: compare between models)
    p_value: float | None = None  # F-test against the rigid model (None for rigid itself)
    depth_scale: float = 1.0
    depth_scale_sigma: float | None = None
    depth_offset_m: float = 0.0
    chosen: bool = False


class CalibrationSummary(Message):
    """The other fit of a calibration (with every sample, or without the outliers)."""

    samples: list[int]
    matrix: list[list[float]]  # 4x4 T_flange_cam
    translation: Vec3
    quaternion_xyzw: Quat
    target_base: Vec3
    spread_mm: Vec3
    passes: bool
    residuals_mm: list[float]
    dissipation_after: float


class CalibrationResult(Message):
    """``T_flange_cam``: maps camera optical frame points into the flange frame (metres)."""

    stamp_ns: int
    parent_frame: str = FLANGE_FRAME
    child_frame: str = CAMERA_FRAME
    matrix: list[list[float]]  # 4x4 T_flange_cam
    translation: Vec3
    quaternion_xyzw: Quat
    rpy: Vec3  # roll, pitch, yaw, radians
    target_base: Vec3  # blob position in the base frame
    spread_mm: Vec3  # per-axis max - min of mapped blob over inliers
    passes: bool  # spread < 10 mm on every axis (the lab's criterion); false when undetermined (no
    # redundancy, or a translation 1-sigma beyond 10 mm: see warnings)
    n_samples: int
    inliers: list[int]
    outliers: list[int]
    residuals_mm: list[float]  # per-sample distance of the mapped blob to target_base
    std_translation_mm: Vec3
    std_rotation_deg: Vec3
    dissipation_before: float | None = None
    dissipation_after: float
    warnings: list[str] = []
    ros1_static_transform: str = ""
    ros2_static_transform: str = ""
    leave_one_out_mm: list[float] = []  # per-sample distance to the target of a fit without it
    noise_scale: float = 1.0  # a-posteriori factor on the modelled noise
    sample_ids: list[int] = []  # ids of the samples (service), in the order of the indices above
    with_all_samples: CalibrationSummary | None = None  # when outliers were excluded
    without_outliers: CalibrationSummary | None = None  # when outliers were found but kept
    camera_correction: CameraCorrection = CameraCorrection()  # apply to camera points before T_flange_cam
    correction_models: list[CorrectionCandidate] = []  # every model tried, the chosen one marked
    correction_reason: str = ""  # why the chosen model was chosen (F-test p-value, AIC)
    noise_mm: float | None = None  # estimated 1-sigma per camera axis of a blob, RMS over the inliers, mm
    # 6x6 covariance of T_flange_cam: (tx, ty, tz) metres, flange frame, then (rx, ry, rz) radians
    # about the flange axes (left perturbation); scaled by the noise estimated from the data
    covariance: list[list[float]] = []
    criterion_advice: list[int] = []  # samples whose removal would make the lab criterion pass (advice)


class CalibrationSamples(Message):
    """The calibrator's samples (reply of ``calibrator/samples``, ``add``, ``remove``, ``reset``)."""

    samples: list[CalibrationSample]


class CalibrationSolveOptions(Message):
    """Payload of ``calibrator/solve`` (every field optional)."""

    loss: str = "linear"  # linear | huber | cauchy
    noise: str = "auto"  # auto (isotropic + the D435's, estimated) | depth | uniform
    correction: str = "auto"  # auto (chosen by an F-test) | rigid | depth_scale | ray_scale
    exclude_outliers: bool = True
    guess: tuple[float, float, float, float, float, float, float] | None = None  # x y z qx qy qz qw
    # eye-in-hand (T_flange_cam, target in the base frame) | eye-to-hand (T_base_cam, target on the flange)
    setup: Literal["eye-in-hand", "eye-to-hand"] = "eye-in-hand"
    # (depth scale, 1-sigma) of an earlier calibration of the same camera, the prior of this one's
    depth_scale_prior: tuple[Finite, Finite] | None = None


class CalibrationRemove(Message):
    """Payload of ``calibrator/remove``."""

    sample_ids: list[int]


class CalibrationFiles(Message):
    """Files written by the calibrator's ``save``: YAML, ROS 1 launch file, ROS 2 command."""

    files: list[str]


def read_calibration_file(path: str | Path) -> tuple[np.ndarray, CameraCorrection]:
    """(``T_flange_cam`` (4, 4), its camera correction) of a saved calibration, YAML or JSON (as
    ``sofia calibrate save`` writes it; a :class:`CalibrationResult` qualifies): ``matrix`` 4 x 4 or
    ``translation`` + ``quaternion_xyzw``, and ``camera_correction`` (identity when absent). Raises
    :class:`FileContentError` naming the file and what is wrong with it."""
    from ..transforms import as_transforms, make_transform  # SciPy: not in every service's image

    try:
        data = load_json_or_yaml(path)
    except OSError as e:
        raise FileContentError(path, f"cannot be read: {e.strerror or e}") from None
    if not isinstance(data, dict):
        raise FileContentError(
            path, f"not a calibration result: expected a mapping, got {type(data).__name__}"
        )
    try:
        if "matrix" in data:
            T = as_transforms(np.array(data["matrix"], dtype=np.float64), "matrix", tol=1e-4)
        elif "translation" in data and "quaternion_xyzw" in data:
            t = np.array(data["translation"], dtype=np.float64)
            if t.shape != (3,):
                raise ValueError(f"translation must be 3 numbers (metres), got shape {t.shape}")
            T = make_transform(t, np.array(data["quaternion_xyzw"], dtype=np.float64))
        else:
            raise ValueError(f"needs 'matrix' or 'translation' + 'quaternion_xyzw', has {sorted(data)}")
        return T, CameraCorrection.model_validate(data.get("camera_correction") or {})
    except ValidationError as e:
        first = e.errors()[0]
        where = ".".join(str(k) for k in ("camera_correction", *first["loc"]))
        raise FileContentError(path, f"{where}: {first['msg']}") from None
    except (ValueError, TypeError) as e:
        raise FileContentError(path, str(e)) from None
