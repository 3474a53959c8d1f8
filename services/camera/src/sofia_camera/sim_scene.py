"""The world the simulated D435 looks at: the calibration blob sheet or the board with objects,
built with the project's Open3D ray caster (``sofia_replay.synth``), and its ground truth.

Everything is in the robot base frame (metres). The board scene is deterministic in its seed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from sofia_replay.synth.calibration import TABLE_Z, CalibrationTarget
from sofia_replay.synth.scene import DEFAULT_T_FLANGE_CAM, build, make_scene
from sofia_schemas import Board
from sofia_schemas.files import FileContentError, load_json_or_yaml
from sofia_schemas.transforms import as_transforms, make_transform

from .errors import BadOption

SceneName = Literal["calibration", "board"]
SCENES: tuple[SceneName, ...] = ("calibration", "board")
KINDS = ("one", "two", "nonred", "empty")
DEFAULT_TARGET = (0.45, 0.25, TABLE_Z + 0.0005)


def parse_T_flange_cam(text: str | None) -> np.ndarray:
    """(4, 4) ``T_flange_cam`` from ``"x y z qx qy qz qw"`` (metres, quaternion x y z w; commas
    allowed) or a YAML/JSON file with ``matrix`` (4x4) or ``translation`` + ``quaternion_xyzw``;
    None gives the synthetic default. BadOption says what is wrong."""
    if text is None:
        return DEFAULT_T_FLANGE_CAM.copy()
    parts = text.replace(",", " ").split()
    try:
        if len(parts) == 7:
            values = np.array([float(v) for v in parts])
            return make_transform(values[:3], values[3:])
        data: Any = load_json_or_yaml(Path(text))
    except (ValueError, OSError, FileContentError) as e:
        raise BadOption(
            "--sim-T-flange-cam", text, f"not 7 numbers 'x y z qx qy qz qw' nor a readable file: {e}"
        ) from None
    if not isinstance(data, dict):
        raise BadOption("--sim-T-flange-cam", text, "file must hold a mapping")
    try:
        if "matrix" in data:
            return as_transforms(np.array(data["matrix"], float), "matrix", tol=1e-4)
        return make_transform(np.array(data["translation"], float), np.array(data["quaternion_xyzw"], float))
    except (KeyError, ValueError, TypeError) as e:
        raise BadOption(
            "--sim-T-flange-cam", text, f"needs 'matrix' or 'translation' + 'quaternion_xyzw': {e}"
        ) from None


@dataclass
class SimOptions:
    """The ``--sim-*`` options (see ``sofia camera serve --help``)."""

    scene: SceneName = "calibration"
    T_flange_cam: np.ndarray = field(default_factory=lambda: DEFAULT_T_FLANGE_CAM.copy())
    target_base: tuple[float, float, float] = DEFAULT_TARGET
    blob_radius: float = 0.015
    seed: int = 0
    kind: str = "one"
    board_file: Path | None = None
    noise: bool = True
    stereo: bool = False  # replay's active-stereo D435 model instead of the simple noise

    def __post_init__(self) -> None:
        if self.scene not in SCENES:
            raise BadOption("--sim-scene", self.scene, f"use one of {list(SCENES)}")
        if self.kind not in KINDS:
            raise BadOption("--sim-kind", self.kind, f"use one of {list(KINDS)}")
        if not 0.001 <= self.blob_radius <= 0.1:
            raise BadOption("--sim-blob-radius", self.blob_radius, "must be within [0.001, 0.1] m")
        self.T_flange_cam = as_transforms(np.asarray(self.T_flange_cam, float), "T_flange_cam", tol=1e-4)


class SimWorld:
    """The ray-casting scene, the colour of each hit, and the truth of one :class:`SimOptions`."""

    def __init__(self, options: SimOptions) -> None:
        self.options = options
        if options.scene == "calibration":
            self.target = CalibrationTarget(
                p_base=np.array(options.target_base, float), radius=options.blob_radius
            )
            self.raycasting, self.colour_of = self.target.build()
            self.scene = None
        else:
            board = Board.from_file(options.board_file) if options.board_file else Board.default()
            rng = np.random.default_rng(options.seed)
            self.scene = make_scene(board, options.kind, rng)  # type: ignore[arg-type]
            self.raycasting, self.colour_of = build(self.scene)

    def truth(self) -> dict[str, Any]:
        """JSON-able ground truth (base frame, metres)."""
        o = self.options
        out: dict[str, Any] = {"scene": o.scene, "seed": o.seed, "T_flange_cam": o.T_flange_cam.tolist()}
        if self.scene is None:
            out["blob"] = {"p_base": list(map(float, self.target.p_base)), "radius": self.target.radius}
        else:
            out["kind"] = o.kind
            out["T_base_board"] = self.scene.T_base_board.tolist()
            out["objects"] = [obj.to_json() for obj in self.scene.objects]
        return out
