"""The files ``save`` writes: the result as YAML, a ROS 1 launch file and a ROS 2 shell line."""

from __future__ import annotations

from pathlib import Path

from sofia_schemas.messages import CalibrationResult

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
