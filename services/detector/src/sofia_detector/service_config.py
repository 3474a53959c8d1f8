"""What ``sofia detector serve`` is started with (:class:`ServiceConfig`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from sofia_runtime.zenoh_config import ZenohOptions
from sofia_schemas import Board, frames

from .params import DetectorParams
from .pick import PickParams


@dataclass
class ServiceConfig:
    board: Board
    robot: str
    zenoh: ZenohOptions
    transform_file: Path | None = None
    params: DetectorParams = field(default_factory=DetectorParams)
    pick: PickParams = field(default_factory=PickParams)
    backlog: int = 1  # clouds kept while busy: 1 keeps only the latest; more absorb a short stall
    camera_frames: tuple[str, ...] = (frames.CAMERA_FRAME,)  # frame ids mapped with T_flange_cam
    pose_wait_s: float = 0.3  # how long a camera cloud waits for the flange pose of its stamp
