"""The live calibrator eye-to-hand: ``sofia calibrator serve --from-clouds --cloud-target ball
--setup eye-to-hand`` as its own process, fed flange poses and the clouds a fixed simulated D435
renders of a ball on the flange (the camera service's eye-to-hand cell), solves T_base_cam."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import zenoh
from scipy.spatial.transform import Rotation
from sofia_calibrator.targets import SphereNotFound, find_ball
from sofia_camera.sim_fixed import DEFAULT_T_BASE_CAM, FixedCameraCell, eye_to_hand_state
from sofia_replay.synth import Camera
from sofia_replay.synth.camera import render
from sofia_schemas.keys import Keys
from sofia_schemas.messages import FlangePose
from sofia_schemas.pointcloud import encode_points
from sofia_schemas.rosmsg import encode_flange_pose
from sofia_schemas.transforms import apply, invert

from ..conftest import gap_mm_deg, query_json
from .test_service import PERIOD_NS, T0_NS, wait_until_served

BALL_FLANGE = (0.01, 0.02, 0.1)
RADIUS = 0.025
T_HOME = np.array([[0.707, -0.707, 0, 0.307], [-0.707, -0.707, 0, 0], [0, 0, -1, 0.59], [0, 0, 0, 1.0]])


def views(n: int, rng: np.random.Generator) -> list[np.ndarray]:
    """n flange poses around the home pose (turned up to 35 deg, shifted up to 10 cm) with the ball
    in the default fixed camera's image."""
    T_home = T_HOME.copy()
    T_home[:3, :3] = Rotation.from_matrix(T_home[:3, :3]).as_matrix()  # orthonormal
    out: list[np.ndarray] = []
    while len(out) < n:
        T = T_home.copy()
        T[:3, :3] = T_home[:3, :3] @ Rotation.from_rotvec(rng.uniform(-0.6, 0.6, 3)).as_matrix()
        T[:3, 3] += rng.uniform(-0.1, 0.1, 3)
        p_cam = apply(invert(DEFAULT_T_BASE_CAM) @ T, np.array(BALL_FLANGE))
        u, v = 615 * p_cam[:2] / p_cam[2] + [320, 240]
        if 60 < u < 580 and 60 < v < 420:
            out.append(T)
    return out


@pytest.mark.parametrize("radius", [RADIUS, None], ids=["radius given", "radius shared by the views"])
def test_the_live_calibrator_solves_eye_to_hand_from_ball_clouds(
    sofia_proc, session, robot_id: str, tmp_path: Path, radius: float | None
) -> None:  # type: ignore[no-untyped-def]
    keys = Keys(robot_id)
    given = [] if radius is None else ["--ball-radius", str(radius)]
    proc = sofia_proc("calibrator", "serve", "--state-dir", str(tmp_path / "state"), "--from-clouds",
                      "--cloud-target", "ball", *given, "--setup", "eye-to-hand")  # fmt: skip
    cell = FixedCameraCell(eye_to_hand_state(DEFAULT_T_BASE_CAM, BALL_FLANGE, RADIUS))
    camera, rng = Camera(), np.random.default_rng(4)
    proc.wait_for_log("calibrator ready")
    wait_until_served(session, keys)
    block = zenoh.CongestionControl.BLOCK  # the service extracts while clouds and poses back up
    poses = session.declare_publisher(keys.flange_pose, congestion_control=block)
    clouds = session.declare_publisher(keys.camera_points, congestion_control=block)
    Ts = views(9, rng)
    for k, T in enumerate(Ts):
        r = render(*cell.scene_at(T), cell.T_base_cam, camera, rng)
        if k == 0:  # the extraction the service runs, here too: the ball is in the frame
            assert abs(find_ball(r.points_cam, r.rgb, RADIUS).sphere.radius_m - RADIUS) < 1e-9
        stamp = T0_NS + k * PERIOD_NS
        for dt in (-100_000_000, 0):
            poses.put(encode_flange_pose(FlangePose.from_matrix(T, stamp + dt)))
        clouds.put(encode_points(r.points_cam, stamp_ns=stamp, frame_id="cam", rgb=r.rgb))
        poses.put(encode_flange_pose(FlangePose.from_matrix(T, stamp + 100_000_000)))
    grey = np.full_like(r.rgb, 128)  # no ball: refused with the reason, the service keeps serving
    try:
        find_ball(r.points_cam, grey)
        raise AssertionError("a grey frame has no ball")
    except SphereNotFound:
        pass
    clouds.put(encode_points(r.points_cam, stamp_ns=T0_NS + 20 * PERIOD_NS, frame_id="cam", rgb=grey))
    proc.wait_for_log("no sphere found", timeout=60)
    proc.wait_for_log(f"solved with {len(Ts)} samples", timeout=60)
    if radius is None:  # each solve refits the centres with one radius (the views' own scatter)
        proc.wait_for_log(f"shared by {len(Ts)} views", timeout=5)
    ok, body = query_json(session, keys.calibrator_op("result"))
    assert ok and body["parent_frame"] == "panda_link0", body
    T_est = np.array(body["matrix"])
    err_mm, err_deg = gap_mm_deg(T_est, DEFAULT_T_BASE_CAM)
    assert err_mm < 1.0 and err_deg < 0.2, (err_mm, err_deg)
    assert 1e3 * np.linalg.norm(np.array(body["target_base"]) - BALL_FLANGE) < 1.0
