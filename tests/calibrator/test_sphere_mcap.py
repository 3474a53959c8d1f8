"""A coloured ball in an MCAP recording's camera clouds (``sofia calibrate --target sphere --mcap``):
the same recording path the blob's ``--from-clouds`` takes, each view's centre by a sphere fit, the
radius given or one radius fitted to all the views."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from sofia_calibrator.errors import InputMismatch
from sofia_calibrator.inputs.mcap import read_mcap
from sofia_camera.sim_fixed import table_and_ball
from sofia_replay.mcap_io import McapWriter
from sofia_replay.synth import Camera
from sofia_replay.synth.calibration import TABLE_Z, CalibrationTarget, random_view
from sofia_replay.synth.camera import render
from sofia_replay.synth.scene import DEFAULT_T_FLANGE_CAM
from sofia_schemas import pointcloud
from sofia_schemas.frames import BASE_FRAME, CAMERA_FRAME
from sofia_schemas.keys import TOPIC_CAMERA_POINTS, TOPIC_FLANGE_POSE
from sofia_schemas.messages import FlangePose

from ..conftest import SOFIA

RADIUS = 0.025
BALL = np.array([0.45, 0.2, TABLE_Z + RADIUS])  # on the table, base frame
START_NS = 1_700_000_000_000_000_000


def _record(path: Path, n: int = 8, seed: int = 0) -> None:
    """n views of the ball from a D435 on the flange (still 0.2 s around each frame), poses and
    organized camera clouds with colour, as the camera service and the arm record them."""
    rng = np.random.default_rng(seed)
    camera = Camera()
    scene = table_and_ball(BALL, RADIUS)
    aim = CalibrationTarget(p_base=BALL)
    with McapWriter(path) as w:
        for i in range(n):
            T_base_cam = random_view(aim, rng, camera, distance=(0.3, 0.5))
            T_base_flange = T_base_cam @ np.linalg.inv(DEFAULT_T_FLANGE_CAM)
            stamp = START_NS + i * 2_000_000_000
            for dt in (-200_000_000, 0, 200_000_000):
                pose = FlangePose.from_matrix(T_base_flange, stamp_ns=stamp + dt, frame_id=BASE_FRAME)
                w.write_flange_pose(TOPIC_FLANGE_POSE, pose)
            r = render(scene[0], scene[1], T_base_cam, camera, rng)
            cdr = pointcloud.encode_points(r.points_cam, stamp_ns=stamp, frame_id=CAMERA_FRAME, rgb=r.rgb)
            w.write_cloud(TOPIC_CAMERA_POINTS, cdr, stamp)


@pytest.mark.parametrize("radius", [None, RADIUS], ids=["radius-fitted", "radius-given"])
def test_balls_in_a_recording_calibrate_from_the_cli(tmp_path: Path, radius: float | None) -> None:
    _record(tmp_path / "ball.mcap")
    args = ["calibrate", "--target", "sphere", "--mcap", str(tmp_path / "ball.mcap"), "--json"]
    r = subprocess.run([SOFIA, *args, *([] if radius is None else ["--radius", str(radius)])],
                       capture_output=True, text=True, timeout=120)  # fmt: skip
    assert r.returncode == 0, r.stderr
    body = json.loads(r.stdout)
    assert 1e3 * np.linalg.norm(np.array(body["translation"]) - DEFAULT_T_FLANGE_CAM[:3, 3]) < 1.0, body
    assert 1e3 * np.linalg.norm(np.array(body["target_base"]) - BALL) < 1.0, body
    assert ("fitted to 8 views" in r.stderr) == (radius is None), r.stderr


def test_the_shared_radius_and_clear_errors(tmp_path: Path) -> None:
    _record(tmp_path / "ball.mcap", n=4, seed=1)
    m = read_mcap(tmp_path / "ball.mcap", from_clouds=True, target="ball")
    assert len(m.p_cam) == 4 and m.radius_m is not None and abs(m.radius_m - RADIUS) < 1e-3
    assert (
        read_mcap(tmp_path / "ball.mcap", from_clouds=True, target="ball", radius_m=RADIUS).radius_m is None
    )
    with pytest.raises(InputMismatch, match="target must be one of"):
        read_mcap(tmp_path / "ball.mcap", from_clouds=True, target="sphere")
    with pytest.raises(InputMismatch, match="no usable samples"):  # no blob in these clouds
        read_mcap(tmp_path / "ball.mcap", from_clouds=True)
