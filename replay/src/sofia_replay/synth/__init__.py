"""Synthetic SofIA data rendered with Open3D ray casting: board scenes and calibration sessions."""

from . import quiet_open3d  # noqa: F401  (first: Open3D's own warnings stay off the terminal)
from .calibration import (
    CalibrationFrame,
    CalibrationSession,
    CalibrationTarget,
    make_calibration_session,
    render_calibration_frame,
)
from .camera import Camera, Render
from .record import write_calibration_session, write_scene_set
from .scene import DEFAULT_T_FLANGE_CAM, ObjectTruth, Scene, SceneFrame, make_scene, render_scene

__all__ = [
    "DEFAULT_T_FLANGE_CAM",
    "CalibrationFrame",
    "CalibrationSession",
    "CalibrationTarget",
    "Camera",
    "ObjectTruth",
    "Render",
    "Scene",
    "SceneFrame",
    "make_calibration_session",
    "make_scene",
    "render_calibration_frame",
    "render_scene",
    "write_calibration_session",
    "write_scene_set",
]
