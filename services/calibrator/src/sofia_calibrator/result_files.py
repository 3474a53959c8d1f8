"""The files ``save`` writes: the result as YAML, a ROS 1 launch file and a ROS 2 shell line."""

from __future__ import annotations

from pathlib import Path

from sofia_schemas.files import FileContentError, load_json_or_yaml
from sofia_schemas.messages import CalibrationResult
from sofia_schemas.messages.calibration import CameraCorrection

from .errors import InputMismatch
from .fitting.prior import ScalePrior
from .formats import to_yaml
from .samples.durable import write_atomic
from .samples.errors import SaveFailed


def save_result(result: CalibrationResult, directory: Path) -> list[str]:
    """Write ``result`` as ``T_flange_cam.yaml``, a ROS 1 launch file and a ROS 2 shell line in
    ``directory``, each file whole, old or new (never half written); the paths written. A failed
    write raises :class:`SaveFailed` naming the file."""
    files = {
        directory / "T_flange_cam.yaml": (to_yaml(result), 0o644),
        directory / "camera_static_transform.launch": (f"<launch>\n  {result.ros1_static_transform}\n</launch>\n", 0o644),
        directory / "camera_static_transform_ros2.sh": (f"#!/bin/sh\n{result.ros2_static_transform}\n", 0o755),
    }  # fmt: skip
    try:
        for path, (text, mode) in files.items():
            write_atomic(path, text.encode(), mode)
    except OSError as e:
        raise SaveFailed(e.filename or str(directory), e.strerror or str(e)) from None
    return [str(p) for p in files]


def read_scale_prior(path: str | Path) -> ScalePrior:
    """The depth scale and its 1-sigma of an earlier calibration's result file (YAML or JSON, as
    ``save`` or ``--yaml`` wrote it), as a prior for calibrating the same camera again."""
    try:
        data = load_json_or_yaml(path)
    except OSError as e:
        raise InputMismatch(f"{path}: cannot be read: {e.strerror or e}") from None
    except FileContentError as e:
        raise InputMismatch(str(e)) from None
    if not isinstance(data, dict) or not isinstance(data.get("camera_correction"), dict):
        raise InputMismatch(f"{path}: not a calibration result (no camera_correction mapping)")
    try:
        corr = CameraCorrection.model_validate(data["camera_correction"])
    except ValueError as e:
        raise InputMismatch(f"{path}: camera_correction: {str(e).splitlines()[-2].strip()}") from None
    if corr.model == "rigid" or corr.depth_scale_sigma is None:
        raise InputMismatch(
            f"{path}: its camera correction is {corr.model}, with no fitted depth scale to use as a prior"
        )
    return ScalePrior(corr.depth_scale, corr.depth_scale_sigma)


def prior_option(path: str | None) -> tuple[float, float] | None:
    """``CalibrationSolveOptions.depth_scale_prior`` from an earlier result file, or None."""
    prior = None if path is None else read_scale_prior(path)
    return None if prior is None else (prior.scale, prior.sigma)
