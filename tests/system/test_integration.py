"""The whole system as separate processes over Zenoh on loopback: replay -> detector -> subscriber,
detect queries, a calibration session replayed into the calibrator, gripper commands through the
emulator, malformed payloads to every queryable, and services killed and restarted mid-stream.

The services are started by :class:`sofia_system.launcher.Launcher`, the code behind ``sofia up``.
"""

from __future__ import annotations

import os
import subprocess
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import zenoh
from sofia_detector.worker import BAD, STALE, UNMAPPED
from sofia_replay import iter_messages, read_truth
from sofia_replay.synth import write_calibration_session, write_scene_set
from sofia_runtime import zenoh_config
from sofia_runtime.client import QueryError, ask
from sofia_schemas import Keys
from sofia_schemas.keys import TOPIC_BLOB, TOPIC_FLANGE_POSE, TOPIC_POINTS
from sofia_schemas.messages import (
    CalibrationResult,
    CalibrationSamples,
    Detection,
    ErrorReply,
    GripperCommand,
    GripperResult,
    ServiceStatus,
)
from sofia_schemas.transforms import rotation_angle
from sofia_system.bus import Collector, wait_until
from sofia_system.launcher import Launcher, ServiceSpec

from ..conftest import SOFIA

CENTRE_TOL_M = 0.008


@dataclass
class System:
    robot: str
    keys: Keys
    launcher: Launcher
    session: zenoh.Session
    scenes: Path
    calib: Path
    tmp: Path

    def replay(self, path: Path, *args: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
        env = dict(os.environ, SOFIA_ROBOT=self.robot)
        cmd = [SOFIA, "replay", "play", str(path), "--robot", self.robot, "--wait-subscribers", "10", *args]
        return subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)

    def healthy(self, timeout: float = 60) -> bool:
        def ok() -> bool:
            self.launcher.poll()
            return all(s == "ok" for s in self.launcher.check_health(self.session, timeout=1.0).values())

        return wait_until(ok, timeout, interval=0.5)


@pytest.fixture(scope="module")
def system(tmp_path_factory: pytest.TempPathFactory) -> Iterator[System]:
    tmp = tmp_path_factory.mktemp("system")
    scenes, calib = tmp / "scenes.mcap", tmp / "calib.mcap"
    write_scene_set(scenes, "mixed", 6, seed=21, rate_hz=10.0, frames="base")
    write_calibration_session(calib, 12, seed=22, clouds=False)
    robot = "sys" + uuid.uuid4().hex[:8]
    specs = [
        ServiceSpec("detector", ["detector", "serve"], "detector"),
        ServiceSpec(
            "calibrator", ["calibrator", "serve", "--state-dir", str(tmp / "calibrator")], "calibrator"
        ),
        ServiceSpec("gripper", ["gripper", "serve", "--emulate", "--object-width", "40"], "gripper"),
    ]
    launcher = Launcher(specs, tmp / "logs", robot)
    launcher.start()
    try:
        with zenoh.open(zenoh_config()) as session:
            s = System(robot, Keys(robot), launcher, session, scenes, calib, tmp)
            if not s.healthy(90):
                logs = "\n".join(
                    f"--- {p.name}\n{p.read_text()[-1500:]}" for p in (tmp / "logs").glob("*.log")
                )
                pytest.fail(f"services not healthy: {launcher.table()}\n{logs}")
            yield s
    finally:  # the services stop whatever failed, so no test leaves processes behind
        launcher.stop()


def _check_detections(dets: list[Detection], truth: dict) -> None:
    """Every frame of ``truth`` has a detection in ``dets``, and each is right."""
    by_stamp = {d.stamp_ns: d for d in dets}
    missing = [f["stamp_ns"] for f in truth["frames"] if f["stamp_ns"] not in by_stamp]
    assert not missing, f"no detection for frames {missing}"
    _check_each(dets, truth)


def _check_each(dets: list[Detection], truth: dict) -> None:
    """Each detection in ``dets`` agrees with the truth of its frame."""
    frames = {f["stamp_ns"]: f for f in truth["frames"]}
    for det in dets:
        frame = frames[det.stamp_ns]
        if not frame["objects"]:
            assert det.status == "no_object" and det.objects == []
            continue
        assert len(det.objects) == len(frame["objects"]), (frame["kind"], det)
        for obj in frame["objects"]:
            err = min(np.linalg.norm(np.array(o.center) - obj["center"]) for o in det.objects)
            assert err < CENTRE_TOL_M, f"{obj['shape']} on {obj['field']}: centre off by {err * 1000:.1f} mm"
        assert [o.allowed for o in det.objects] == sorted((o.allowed for o in det.objects), reverse=True)


def test_replay_to_detector_gives_the_right_centre_for_every_frame(system: System) -> None:
    truth = read_truth(system.scenes)
    assert truth is not None
    dets = Collector(system.session, system.keys.detections, Detection)
    time.sleep(0.5)
    played = system.replay(system.scenes, "--topic", TOPIC_POINTS)
    assert played.returncode == 0, played.stderr
    assert wait_until(lambda: len(dets) >= len(truth["frames"]), 20)
    dets.close()
    assert len(dets.items) == len(truth["frames"])  # exactly one detection per cloud
    _check_detections(dets.items, truth)
    counters = ask(system.session, system.keys.status("detector"), ServiceStatus).counters
    assert counters["shm_read"] >= 1 and counters["shm_copied"] == 0, counters  # read in place, none refused


def test_detect_queries_latest_and_given_cloud(system: System) -> None:
    truth = read_truth(system.scenes)
    assert truth is not None
    system.replay(system.scenes, "--topic", TOPIC_POINTS, "--fast")
    time.sleep(1.0)
    latest = ask(system.session, system.keys.detect, Detection, timeout=20)
    assert latest.stamp_ns == truth["frames"][-1]["stamp_ns"]
    # a query carrying a cloud gets the detection of that cloud
    msg = next(m for m in iter_messages(system.scenes, topics=[TOPIC_POINTS]))
    det = ask(system.session, system.keys.detect, Detection, payload=msg.data, timeout=20)
    assert det.stamp_ns == msg.log_time_ns
    _check_detections([det], {"frames": [truth["frames"][0]]})


def test_calibration_session_replayed_into_the_calibrator(system: System) -> None:
    truth = read_truth(system.calib)
    assert truth is not None
    replies = list(system.session.get(system.keys.calibrator_op("reset"), timeout=10))
    assert replies and replies[0].ok is not None
    played = system.replay(system.calib, "--topic", TOPIC_BLOB, "--topic", TOPIC_FLANGE_POSE, "--rate", "8")
    assert played.returncode == 0, played.stderr

    def solved() -> bool:
        try:
            res = ask(system.session, system.keys.calibrator_op("result"), CalibrationResult, timeout=5)
        except QueryError:
            return False
        return res.n_samples == len(truth["frames"])

    assert wait_until(solved, 30), "the calibrator did not use every sample"
    res = ask(system.session, system.keys.calibrator_op("result"), CalibrationResult)
    T, T_true = np.array(res.matrix), np.array(truth["T_flange_cam"])
    assert np.linalg.norm(T[:3, 3] - T_true[:3, 3]) < 0.003
    assert np.degrees(rotation_angle(T[:3, :3].T @ T_true[:3, :3])) < 0.5
    assert res.passes


def _command(system: System, **kw: object) -> GripperResult:
    cmd = GripperCommand.model_validate(kw)
    return ask(system.session, system.keys.gripper_command, GripperResult, cmd.model_dump_json(), timeout=20)


def test_gripper_commands_through_the_emulator(system: System) -> None:
    opened = _command(system, action="open")
    assert opened.ok, opened.reason
    grasp = _command(system, action="grasp", force_n=10.0)
    assert grasp.ok and grasp.grasped, grasp.reason
    assert grasp.opening_mm is not None and abs(grasp.opening_mm - 40.0) < 3.0
    released = _command(system, action="release")
    assert released.ok, released.reason
    assert released.opening_mm is not None and released.opening_mm > 45.0


PAYLOAD_QUERYABLES = (
    ("detector", "detector/detect"),
    ("calibrator", "calibrator/add"),
    ("calibrator", "calibrator/remove"),
    ("calibrator", "calibrator/solve"),
    ("gripper", "gripper/command"),
)
MALFORMED = (b"\xff\xfe garbage", b'{"not": "a valid message"}', b"\x00\x01\x00\x00\x01")


@pytest.mark.parametrize(("service", "suffix"), PAYLOAD_QUERYABLES)
def test_malformed_payloads_get_error_replies(system: System, service: str, suffix: str) -> None:
    key = f"{system.keys.prefix}/{suffix}"
    for payload in MALFORMED:
        replies = list(system.session.get(key, payload=payload, timeout=10))
        assert len(replies) == 1, f"{key}: {len(replies)} replies to {payload!r}"
        err = replies[0].err
        assert err is not None, f"{key} accepted {payload!r}"
        reply = ErrorReply.model_validate_json(err.payload.to_bytes())
        assert reply.message, reply
    status = ask(system.session, system.keys.status(service), ServiceStatus)
    # still serving; the detector may be degraded by clouds it shed on a loaded host, never by queries
    cloud_drops = status.state == "degraded" and service == "detector"
    assert status.state == "ok" or cloud_drops, status
    if cloud_drops:
        reasons = [part.split(":")[0] for part in status.detail.split("; ")]
        assert set(reasons) <= {STALE, UNMAPPED, BAD}, status.detail


def _sample_ids(system: System) -> list[int]:
    """The ids of the calibrator's samples (one page: these tests add fewer than its size)."""
    page = ask(system.session, system.keys.calibrator_op("samples"), CalibrationSamples, timeout=10)
    return [s.sample_id for s in page.samples if s.sample_id is not None]


def test_services_killed_mid_stream_come_back(system: System) -> None:
    """Kill each service hard while clouds stream; the launcher restarts it and work resumes."""
    truth = read_truth(system.scenes)
    assert truth is not None
    if not _sample_ids(system):  # run on its own: give the calibrator samples to come back with
        played = system.replay(
            system.calib, "--topic", TOPIC_BLOB, "--topic", TOPIC_FLANGE_POSE, "--rate", "8"
        )
        assert played.returncode == 0, played.stderr
        assert wait_until(lambda: len(_sample_ids(system)) >= 3, 30)
    ids_before = _sample_ids(system)
    dets = Collector(system.session, system.keys.detections, Detection)
    env = dict(os.environ, SOFIA_ROBOT=system.robot)
    player = subprocess.Popen(
        [SOFIA, "replay", "play", str(system.scenes), "--topic", TOPIC_POINTS, "--loop", "--no-restamp",
         "--robot", system.robot],  # recorded stamps: each detection is matched to its frame's truth
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    try:
        assert wait_until(lambda: len(dets) > 3, 20)
        for name in ("detector", "calibrator", "gripper"):
            proc = system.launcher.procs[name].popen
            assert proc is not None
            proc.kill()
            proc.wait(10)
            n = len(dets)
            assert system.healthy(60), system.launcher.table()
            assert system.launcher.procs[name].restarts >= 1
            # the subscriber keeps receiving detections (from the restarted detector, too)
            assert wait_until(lambda n=n: len(dets) > n + 3, 30)
        # the detector drops stale clouds while it restarts, so not every frame has a detection;
        # every detection it published is right
        _check_each(dets.items, truth)
    finally:
        player.terminate()
        player.wait(10)
        dets.close()
    # the calibrator resumed with its samples from its store, and solves with them all
    assert _sample_ids(system) == ids_before
    res = ask(system.session, system.keys.calibrator_op("result"), CalibrationResult, timeout=10)
    assert res.n_samples == len(ids_before)
    assert _command(system, action="open").ok


def test_router_restart(tmp_path: Path) -> None:
    """Services that reach each other only through a router (as in compose) survive its restart."""
    port = 17000 + int(uuid.uuid4().int % 2000)
    endpoint = f"tcp/127.0.0.1:{port}"
    robot = "rr" + uuid.uuid4().hex[:8]
    env = dict(os.environ, SOFIA_ZENOH_MODE="client", SOFIA_ZENOH_CONNECT=endpoint)
    router = Launcher(
        [ServiceSpec("router", ["router", "--listen", endpoint])], tmp_path / "r", robot, restart=False
    )
    det = Launcher(
        [ServiceSpec("detector", ["detector", "serve"], "detector")], tmp_path / "d", robot, env=env
    )
    scenes = tmp_path / "one.mcap"
    write_scene_set(scenes, "one", 2, seed=5, rate_hz=5.0, frames="base")
    router.start()
    det.start()
    try:
        with zenoh.open(zenoh_config(env=env)) as session:
            keys = Keys(robot)
            dets = Collector(session, keys.detections, Detection)
            player = subprocess.Popen(
                [SOFIA, "replay", "play", str(scenes), "--loop", "--robot", robot],
                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            )  # fmt: skip
            try:
                assert wait_until(lambda: len(dets) >= 2, 60), det.table()
                router.stop()
                time.sleep(2.0)
                router.start()
                n = len(dets)
                assert wait_until(lambda: len(dets) > n + 2, 60), (
                    "detections did not resume after the router restart"
                )
            finally:
                player.terminate()
                player.wait(10)
                dets.close()
    finally:
        det.stop()
        router.stop()
