"""Calibration samples and results."""

from __future__ import annotations

from pydantic import Field

from .base import Message, Quat, Vec3


class CalibrationSample(Message):
    """One blob observation paired with the flange pose at its stamp."""

    stamp_ns: int
    p_cam: Vec3  # blob, camera optical frame, metres
    translation: Vec3  # T_base_flange translation, metres
    rotation_xyzw: Quat  # T_base_flange rotation, x y z w
    confidence: float = Field(1.0, ge=0.0, le=1.0)
    sample_id: int | None = None


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
    parent_frame: str = "panda_link8"
    child_frame: str = "panda_camera"
    matrix: list[list[float]]  # 4x4 T_flange_cam
    translation: Vec3
    quaternion_xyzw: Quat
    rpy: Vec3  # roll, pitch, yaw, radians
    target_base: Vec3  # blob position in the base frame
    spread_mm: Vec3  # per-axis max - min of mapped blob over inliers
    passes: bool  # spread < 10 mm on every axis (the lab's criterion)
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


class CalibrationSamples(Message):
    """The calibrator's samples (reply of ``calibrator/samples``, ``add``, ``remove``, ``reset``)."""

    samples: list[CalibrationSample]


class CalibrationSolveOptions(Message):
    """Payload of ``calibrator/solve`` (every field optional)."""

    loss: str = "linear"  # linear | huber | cauchy
    noise: str = "depth"  # depth | uniform
    exclude_outliers: bool = True
    guess: tuple[float, float, float, float, float, float, float] | None = None  # x y z qx qy qz qw


class CalibrationRemove(Message):
    """Payload of ``calibrator/remove``."""

    sample_ids: list[int]


class CalibrationFiles(Message):
    """Files written by the calibrator's ``save``: YAML, ROS 1 launch file, ROS 2 command."""

    files: list[str]
