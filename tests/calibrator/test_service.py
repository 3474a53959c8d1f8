"""``sofia calibrator`` as a separate process over Zenoh: online samples, queries, bad input, a
kill and a restart that resumes from the append-only log."""

from __future__ import annotations

import json
import sqlite3
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import zenoh
from sofia_calibrator import calibrate
from sofia_calibrator.fitting.simulate import make_problem
from sofia_schemas.keys import Keys
from sofia_schemas.messages import BlobObservation, CalibrationResult, FlangePose
from sofia_schemas.rosmsg import encode_blob, encode_flange_pose

from ..conftest import query_json

T0_NS = 1_700_000_000_000_000_000
PERIOD_NS = 1_000_000_000


def wait_until_served(session: zenoh.Session, keys: Keys, timeout: float = 40.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if list(session.get(keys.calibrator_op("samples"), timeout=1.0)):
            return
        time.sleep(0.1)
    raise AssertionError("calibrator queryables not reachable")


def publish_sample(session: zenoh.Session, keys: Keys, k: int, p_cam: np.ndarray, T: np.ndarray,
                   T_moving: np.ndarray | None = None) -> None:  # fmt: skip
    """Poses 0.1 s before, at and after the blob stamp (still, unless ``T_moving`` is given), then the blob."""
    stamp = T0_NS + k * PERIOD_NS
    for dt, pose in ((-100_000_000, T), (0, T), (100_000_000, T if T_moving is None else T_moving)):
        session.put(keys.flange_pose, encode_flange_pose(FlangePose.from_matrix(pose, stamp + dt)))
    session.put(keys.blob, encode_blob(BlobObservation(stamp_ns=stamp, position=tuple(map(float, p_cam)))))  # type: ignore[arg-type]


def wait_for(pred: Callable[[], bool], timeout: float = 40.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if pred():
            return
        time.sleep(0.05)
    raise AssertionError("condition not met in time")


def test_service_online_queries_errors_and_restart(
    sofia_proc, session, collect, robot_id: str, tmp_path: Path
) -> None:  # type: ignore[no-untyped-def]
    keys = Keys(robot_id)
    state = tmp_path / "state"
    proc = sofia_proc("calibrator", "serve", "--state-dir", str(state))
    proc.wait_for_log("calibrator ready")
    wait_until_served(session, keys)

    got = collect(keys.calibration_result)

    def results() -> list[CalibrationResult]:
        return got.models(keys.calibration_result, CalibrationResult)

    time.sleep(0.5)
    pr = make_problem(8, np.random.default_rng(21))
    for k in range(8):
        publish_sample(session, keys, k, pr.p_cam[k], pr.T_base_flange[k])
    moving = pr.T_base_flange[0].copy()
    moving[:3, 3] += [0.05, 0.0, 0.0]
    publish_sample(session, keys, 20, pr.p_cam[1], pr.T_base_flange[1], T_moving=moving)
    # a malformed blob and a malformed pose: logged and dropped, the service keeps serving
    session.put(keys.blob, b"\x00\x01garbage")
    session.put(keys.flange_pose, b'{"stamp_ns": 1, "translation": [0, 0, "x"]}')

    wait_for(lambda: bool(results()) and results()[-1].n_samples == 8)
    proc.wait_for_log("the flange was moving", timeout=40)
    last = results()[-1]
    assert np.abs(np.array(last.matrix) - pr.T_flange_cam).max() < 0.01
    assert last.passes and last.sample_ids == list(range(8))
    # the service solves as `sofia calibrate` does by default: noise and correction from the data
    offline = calibrate(pr.p_cam, pr.T_base_flange)
    assert np.abs(np.array(last.matrix) - offline.T_flange_cam).max() < 1e-6
    assert last.noise_mm == pytest.approx(offline.noise_mm, rel=1e-4)
    assert last.camera_correction.model == offline.correction.model and len(last.correction_models) == 2
    assert np.allclose(last.covariance, offline.covariance6, rtol=1e-3, atol=1e-15)

    ok, body = query_json(session, keys.calibrator_op("result"))
    assert ok and body["n_samples"] == 8 and len(body["matrix"]) == 4
    ok, body = query_json(session, keys.status("calibrator"))
    assert ok and body["service"] == "calibrator" and body["counters"]["samples"] == 8

    # add and remove through queries
    s = {"stamp_ns": 5, "p_cam": list(pr.p_cam[2]), "translation": list(pr.T_base_flange[2, :3, 3]),
         "rotation_xyzw": [0.0, 0.0, 0.0, 1.0]}  # fmt: skip
    ok, body = query_json(session, keys.calibrator_op("add"), json.dumps(s))
    assert ok and body["samples"][0]["sample_id"] == 8
    ok, body = query_json(session, keys.calibrator_op("remove"), json.dumps({"sample_ids": [8]}))
    assert ok and [x["sample_id"] for x in body["samples"]] == list(range(8))

    # bad input gets an error reply naming what was wrong
    ok, body = query_json(session, keys.calibrator_op("add"), '{"p_cam": [0, 0, "nan"]}')
    assert not ok and body["error"] == "ValidationError" and "p_cam" in body["message"]
    ok, body = query_json(session, keys.calibrator_op("remove"), json.dumps({"sample_ids": [99]}))
    assert not ok and "no sample with id 99" in body["message"]
    ok, body = query_json(session, keys.calibrator_op("solve"), json.dumps({"loss": "l1"}))
    assert not ok and "loss must be one of" in body["message"]
    ok, body = query_json(session, keys.calibrator_op("solve"), json.dumps({"noise": "gaussian"}))
    assert not ok and "'auto', 'depth', 'uniform'" in body["message"] and "'gaussian'" in body["message"]
    ok, body = query_json(
        session, keys.calibrator_op("solve"), json.dumps({"noise": "depth", "correction": "depth_scale"})
    )
    assert ok and body["camera_correction"]["model"] == "depth_scale" and body["noise_mm"] > 0
    ok, body = query_json(
        session, keys.calibrator_op("solve"), json.dumps({"loss": "huber", "noise": "uniform"})
    )
    assert ok and body["n_samples"] == 8

    ok, body = query_json(session, keys.calibrator_op("save"))
    assert ok and all(Path(f).is_file() for f in body["files"])
    assert "panda_link8 camera_color_optical_frame" in (state / "camera_static_transform.launch").read_text()

    # a crash loses nothing: the restarted calibrator resumes and publishes the same result
    proc.kill()
    with sqlite3.connect(state / "samples.db") as db:  # 8 + add - remove, committed
        assert db.execute("SELECT COUNT(*) FROM samples").fetchone()[0] == 8
    got.clear()
    frames = ("--parent-frame", "tool_flange", "--child-frame", "d435_color_optical_frame")
    proc2 = sofia_proc("calibrator", "serve", "--state-dir", str(state), *frames)
    proc2.wait_for_log("calibrator ready")
    assert "resumed 8 samples" in proc2.log()
    wait_until_served(session, keys)
    ok, body = query_json(session, keys.calibrator_op("samples"))
    assert ok and len(body["samples"]) == 8
    ok, body = query_json(session, keys.calibrator_op("result"))
    assert ok and np.abs(np.array(body["matrix"]) - np.array(last.matrix)).max() < 1e-9
    assert (body["parent_frame"], body["child_frame"]) == ("tool_flange", "d435_color_optical_frame")
    assert "tool_flange d435_color_optical_frame" in body["ros1_static_transform"]

    # with too few samples left, no result of the removed samples is kept
    ok, body = query_json(
        session, keys.calibrator_op("remove"), json.dumps({"sample_ids": [0, 1, 2, 3, 4, 5]})
    )
    assert ok and len(body["samples"]) == 2
    ok, body = query_json(session, keys.calibrator_op("result"))
    assert not ok and "2 samples, at least 3 needed" in body["message"]

    ok, body = query_json(session, keys.calibrator_op("reset"))
    assert ok and body["samples"] == []
    ok, body = query_json(session, keys.calibrator_op("result"))
    assert not ok and "no result yet" in body["message"]
    assert proc2.stop() == 0


def test_service_extracts_the_blob_from_camera_clouds(
    sofia_proc, session, robot_id: str, tmp_path: Path
) -> None:  # type: ignore[no-untyped-def]
    from sofia_replay.synth.calibration import make_calibration_session
    from sofia_schemas.pointcloud import encode_points

    keys = Keys(robot_id)
    proc = sofia_proc("calibrator", "serve", "--state-dir", str(tmp_path / "state"), "--from-clouds")
    proc.wait_for_log("calibrator ready")
    wait_until_served(session, keys)
    # BLOCK: while the service extracts a blob, a 4.9 MB cloud and the poses around it back up, and
    # Zenoh's default (drop) would lose some of them before they reach the service
    poses = session.declare_publisher(keys.flange_pose, congestion_control=zenoh.CongestionControl.BLOCK)
    clouds = session.declare_publisher(keys.camera_points, congestion_control=zenoh.CongestionControl.BLOCK)
    cal_session = make_calibration_session(5, np.random.default_rng(9))
    for k, f in enumerate(cal_session.frames):
        stamp = T0_NS + k * PERIOD_NS
        for dt in (-100_000_000, 0):
            poses.put(encode_flange_pose(FlangePose.from_matrix(f.T_base_flange, stamp + dt)))
        clouds.put(encode_points(f.points_cam, stamp_ns=stamp, frame_id="cam", rgb=f.rgb))
        poses.put(encode_flange_pose(FlangePose.from_matrix(f.T_base_flange, stamp + 100_000_000)))
    rgb = cal_session.frames[0].rgb.copy()
    rgb[:] = 240  # no blob in view: rejected with the reason, the service keeps running
    clouds.put(
        encode_points(
            cal_session.frames[0].points_cam, stamp_ns=T0_NS + 9 * PERIOD_NS, frame_id="cam", rgb=rgb
        )
    )
    proc.wait_for_log("no blob found", timeout=60)
    proc.wait_for_log("solved with 5 samples", timeout=60)
    ok, body = query_json(session, keys.calibrator_op("result"))
    assert ok and body["n_samples"] == 5 and body["parent_frame"] == "panda_link8"
    assert np.linalg.norm(np.array(body["translation"]) - cal_session.T_flange_cam[:3, 3]) < 0.005
    ok, body = query_json(session, keys.status("calibrator"))
    assert ok and body["counters"]["dropped_clouds"] == 0 and body["counters"]["samples"] == 5


def test_service_solves_with_an_earlier_calibrations_scale(
    sofia_proc, session, collect, robot_id: str, tmp_path: Path, lab_dir: Path
) -> None:  # type: ignore[no-untyped-def]
    from sofia_calibrator import read_lab

    keys = Keys(robot_id)
    p, T = read_lab(lab_dir / "poses.txt", lab_dir / "tfs.txt")
    earlier = tmp_path / "earlier.yaml"
    earlier.write_text(
        "camera_correction:\n  model: depth_scale\n  depth_scale: 0.9494\n  depth_scale_sigma: 0.0069\n"
    )
    proc = sofia_proc(
        "calibrator", "serve", "--state-dir", str(tmp_path / "state"), "--scale-prior", str(earlier)
    )
    proc.wait_for_log("calibrator ready")
    wait_until_served(session, keys)
    got = collect(keys.calibration_result)
    time.sleep(0.5)
    for k in range(6):
        publish_sample(session, keys, k, p[k], T[k])
    wait_for(lambda: any(r.n_samples == 6 for r in got.models(keys.calibration_result, CalibrationResult)))
    last = [r for r in got.models(keys.calibration_result, CalibrationResult) if r.n_samples == 6][-1]
    offline = calibrate(p[:6], T[:6], depth_scale_prior=(0.9494, 0.0069))
    assert last.correction_reason == offline.correction_reason
    assert last.correction_reason.startswith("depth_scale: prior 0.9494"), last.correction_reason
    assert np.abs(np.array(last.matrix) - offline.T_flange_cam).max() < 1e-6
    # a caller's options may drop the prior, or give one that cannot apply (one clear line)
    ok, body = query_json(session, keys.calibrator_op("solve"), "{}")
    assert ok and "prior" not in body["correction_reason"], body["correction_reason"]
    bad = {"depth_scale_prior": [0.95, 0.01], "correction": "rigid"}
    ok, body = query_json(session, keys.calibrator_op("solve"), json.dumps(bad))
    assert not ok and "needs correction 'auto' or 'depth_scale'" in body["message"], body
