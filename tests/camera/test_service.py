"""``sofia camera serve --sim`` and the detector as separate processes on Zenoh: the simulated D435
renders the board from the flange pose a "robot" (this test) publishes, the detector maps its
camera-frame clouds with that pose and the true T_flange_cam and finds the object; the clouds
carry the poses' stamps; ``sofia camera record`` writes an MCAP the replayer reads."""

from __future__ import annotations

import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import yaml
import zenoh
from scipy.spatial.transform import Rotation
from sofia_camera.camera_info import decode_camera_info
from sofia_camera.meta import CloudMeta
from sofia_camera.sim_scene import SimOptions, SimWorld
from sofia_replay import iter_messages
from sofia_replay.synth.camera import look_at
from sofia_runtime import zenoh_config
from sofia_runtime.client import ask
from sofia_schemas import Keys, pointcloud
from sofia_schemas.keys import TOPIC_CAMERA_INFO, TOPIC_CAMERA_POINTS, TOPIC_FLANGE_POSE
from sofia_schemas.messages import Detection, FlangePose, ServiceStatus
from sofia_schemas.rosmsg import encode_flange_pose
from sofia_schemas.transforms import invert, matrix_to_quat_xyzw
from sofia_system.bus import Collector, wait_until

from ..conftest import SOFIA

SEED = 5
DETECTOR_MAX_ERROR_M = 0.008  # the detector's accuracy target: p95 <= 5 mm, max <= 8 mm


def _T_flange_cam() -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("zxy", [80.0, -12.0, 5.0], degrees=True).as_matrix()
    T[:3, 3] = [0.06, -0.01, 0.05]
    return T


class PosePublisher:
    """A stand-in arm: publishes ``T_base_flange`` at 100 Hz (CDR TransformStamped, stamp = now)."""

    def __init__(self, session: zenoh.Session, key: str, T_base_flange: np.ndarray) -> None:
        self.pub = session.declare_publisher(key)
        self.T = T_base_flange
        self.stamps: set[int] = set()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self) -> None:
        q = matrix_to_quat_xyzw(self.T[:3, :3])
        while not self.stop.wait(0.01):
            stamp = time.time_ns()
            pose = FlangePose(stamp_ns=stamp, translation=tuple(self.T[:3, 3]), rotation_xyzw=tuple(q))
            self.pub.put(encode_flange_pose(pose))
            self.stamps.add(stamp)


def test_simulated_camera_feeds_the_detector(sofia_proc, robot_id: str, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    T_flange_cam = _T_flange_cam()
    t, q = T_flange_cam[:3, 3], matrix_to_quat_xyzw(T_flange_cam[:3, :3])
    world = SimWorld(SimOptions(scene="board", seed=SEED, T_flange_cam=T_flange_cam))
    truth = world.truth()
    centre = np.array(truth["objects"][0]["center"])
    board_centre = np.array(truth["T_base_board"])[:3, 3]
    T_base_cam = look_at(
        board_centre + np.array([0.0, 0.0, 0.75]), board_centre, np.array(truth["T_base_board"])[:3, 1]
    )
    transform = tmp_path / "T_flange_cam.yaml"
    transform.write_text(yaml.safe_dump({"matrix": T_flange_cam.tolist()}))

    sofia_proc("camera", "serve", "--sim", "--sim-scene", "board", "--sim-seed", str(SEED),
               "--sim-T-flange-cam", " ".join(f"{v:.12f}" for v in (*t, *q)))  # fmt: skip
    detector = sofia_proc("detector", "serve", "--transform", str(transform))
    keys = Keys(robot_id)
    with zenoh.open(zenoh_config()) as session:
        detections = Collector(session, keys.detections, Detection)
        clouds: list[tuple[int, CloudMeta]] = []
        infos: list[int] = []
        session.declare_subscriber(keys.camera_points, lambda s: clouds.append(
            (pointcloud.decode(s.payload.to_bytes()).stamp_ns, CloudMeta.from_attachment(s.attachment.to_bytes() if s.attachment else b""))))  # fmt: skip
        session.declare_subscriber(keys.camera_info, lambda s: infos.append(
            (lambda h: h.sec * 1_000_000_000 + h.nanosec)(decode_camera_info(s.payload.to_bytes()).header.stamp)))  # fmt: skip
        detector.wait_for_log("detector ready", timeout=90)
        arm = PosePublisher(session, keys.flange_pose, T_base_cam @ invert(T_flange_cam))
        try:
            found = wait_until(lambda: sum(bool(d.objects) for d in detections.items) >= 3, 120, 0.2)
            assert found, f"{len(clouds)} clouds, detections: {detections.items[-3:]}"
            status = ask(session, keys.status("camera"), ServiceStatus, timeout=10)
            out = tmp_path / "camera.mcap"
            rec = subprocess.run([SOFIA, "camera", "record", str(out), "--seconds", "3", "--robot", robot_id],
                                 capture_output=True, text=True, timeout=60)  # fmt: skip
        finally:
            arm.stop.set()
            arm.thread.join(2)
    errors = [np.linalg.norm(np.array(d.objects[0].center) - centre) for d in detections.items if d.objects]
    assert max(errors) <= DETECTOR_MAX_ERROR_M, f"centre errors {np.round(np.array(errors) * 1e3, 2)} mm"
    assert all(
        d.objects[0].field == tuple(truth["objects"][0]["field"]) for d in detections.items if d.objects
    )
    stamps = [s for s, _ in clouds]
    assert set(stamps) <= arm.stamps, "every cloud carries the stamp of a flange pose"
    assert stamps == sorted(stamps) and len(set(stamps)) == len(stamps)
    assert all(m.simulated and m.synced and not m.depth_corrected for _, m in clouds)
    assert set(infos) & set(stamps), "camera info is stamped like the clouds"
    assert status.state == "ok" and status.info["simulated"] is True and status.counters["published"] > 0
    assert status.info["shm"] is True and status.counters["shm_direct"] > 0, "clouds written into Zenoh SHM"
    assert status.counters["shm_copied"] == 0
    assert status.counters["shm_direct"] + status.counters["shm_fallbacks"] >= status.counters["published"]
    assert rec.returncode == 0, rec.stdout + rec.stderr
    topics = [m.topic for m in iter_messages(out)]
    for topic in (TOPIC_CAMERA_POINTS, TOPIC_CAMERA_INFO, TOPIC_FLANGE_POSE):
        assert topics.count(topic) > 0, f"{topic} missing from the recording: {rec.stdout}"


def test_bad_options_are_refused_with_the_reason() -> None:
    r = subprocess.run([SOFIA, "camera", "serve", "--width", "1000", "--height", "480"],
                       capture_output=True, text=True, timeout=60)  # fmt: skip
    assert r.returncode == 2 and "1000x480" in r.stderr and "640x480" in r.stderr, r.stderr
    r = subprocess.run(
        [SOFIA, "camera", "serve", "--filters", "spatial,blur"], capture_output=True, text=True, timeout=60
    )
    assert r.returncode == 2 and "blur" in r.stderr, r.stderr
    r = subprocess.run(
        [SOFIA, "camera", "serve", "--align", "fast"], capture_output=True, text=True, timeout=60
    )
    assert r.returncode == 2 and "fast" in r.stderr and "registration" in r.stderr, r.stderr


def test_without_a_camera_the_service_says_so_and_keeps_serving(sofia_proc, robot_id: str) -> None:  # type: ignore[no-untyped-def]
    proc = sofia_proc("camera", "serve", "--serial", "000000000000")
    proc.wait_for_log("camera ready", timeout=60)
    with zenoh.open(zenoh_config()) as session:
        deadline = time.monotonic() + 30
        while True:
            status = ask(session, Keys(robot_id).status("camera"), ServiceStatus, timeout=10)
            if status.state == "error" or time.monotonic() > deadline:
                break
            time.sleep(0.5)
    assert status.state == "error" and "no RealSense camera 000000000000 connected" in status.detail, status
    assert status.counters["published"] == 0 and proc.popen.poll() is None
