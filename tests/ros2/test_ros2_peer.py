"""A ROS 2 peer (zenoh-ros2-sdk, separate process, through the router) sees SofIA's graph, receives
every detection of a replay as ``vision_msgs/msg/Detection3DArray`` and calls ``detect_object``."""

from __future__ import annotations

import json
import queue
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import zenoh
from sofia_replay.synth import make_scene, render_scene
from sofia_replay.synth.record import write_scene_set
from sofia_runtime.zenoh_config import ZenohOptions, zenoh_config
from sofia_schemas import Board, pointcloud
from sofia_schemas.keys import Keys
from sofia_schemas.messages import Detection

N_FRAMES = 6


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    path = tmp_path_factory.mktemp("ros2") / "scenes.mcap"
    truth = write_scene_set(path, kind="mixed", n=N_FRAMES, seed=3, frames="base")
    return path, truth


def test_ros2_peer_discovers_subscribes_and_calls(  # type: ignore[no-untyped-def]
    bus, peer, sofia_proc, robot_id: str, recording, tmp_path: Path
) -> None:
    path, truth = recording
    rng = np.random.default_rng(11)
    scene = make_scene(Board.default(), "one", rng, shape="box", fld=(1, 1))
    frame = render_scene(scene, rng)
    cloud_file = tmp_path / "cloud.cdr"
    cloud_file.write_bytes(
        bytes(pointcloud.encode_points(frame.points_base, stamp_ns=42, frame_id="panda_link0"))
    )

    detector = sofia_proc("detector", "serve", "--backlog", "16", env=bus.env)
    calibrator = sofia_proc("calibrator", "serve", "--state-dir", str(tmp_path / "cal"), env=bus.env)
    bridge = sofia_proc("ros2", "serve", env=bus.env)
    detector.wait_for_log("detector ready")
    bridge.wait_for_log("ros2 ready")
    p = peer("--cloud", str(cloud_file), "--calibrator", "samples")

    # discovery, the rmw_zenoh way (liveliness tokens): ros2 topic list -t / ros2 service list -t
    graph = p.next("graph", timeout=60)
    ns = f"/sofia/{robot_id}"
    topics, services = graph["topics"], graph["services"]
    assert topics[f"{ns}/detections"] == ["vision_msgs/msg/Detection3DArray"]
    assert topics[f"{ns}/points"] == topics[f"{ns}/camera/points"] == ["sensor_msgs/msg/PointCloud2"]
    assert topics[f"{ns}/pick_target"] == ["geometry_msgs/msg/PoseStamped"]
    assert topics["/tf"] == topics["/tf_static"] == ["tf2_msgs/msg/TFMessage"]
    assert topics[f"{ns}/gripper/joint_states"] == ["sensor_msgs/msg/JointState"]
    assert services[f"{ns}/detect_object"] == ["sofia_msgs/srv/DetectObject"]
    for op in ("add", "remove", "reset", "solve", "save", "samples", "result"):
        assert services[f"{ns}/calibrator/{op}"] == ["sofia_msgs/srv/JsonQuery"]
    p.next("ready")

    # the service: a base-frame cloud in, the centroid and every object out
    response = p.next("response", timeout=60)
    assert response is not None, "detect_object did not answer"
    truth_center = np.array(scene.objects[0].center)
    assert response["success"] and response["status"] == "ok" and response["frame_id"] == "panda_link0"
    assert response["stamp_ns"] == 42
    assert np.linalg.norm(np.array(response["center"]) - truth_center) < 0.005
    assert 0.0 < np.linalg.norm(np.array(response["centroid"]) - truth_center) < 0.05
    assert [(o["row"], o["col"], o["allowed"]) for o in response["objects"]] == [(1, 1, True)]

    # the calibrator's queryables are ROS 2 services too (JSON in and out)
    answer = p.next("calibrator", timeout=60)
    assert answer is not None and answer["success"], answer
    assert json.loads(answer["json"])["samples"] == []

    # a replay: every JSON detection on the bus arrives at the ROS 2 peer as a Detection3DArray
    conf = zenoh_config(ZenohOptions(mode="client", connect=[f"tcp/127.0.0.1:{bus.port}"]))
    with zenoh.open(conf) as session:
        sofia_dets: queue.Queue[bytes] = queue.Queue()
        _sub = session.declare_subscriber(
            Keys(robot_id).detections, lambda s: sofia_dets.put(s.payload.to_bytes())
        )
        play = sofia_proc("replay", "play", str(path), "--topic", "/pc_glob", "--rate", "2",
                          "--wait-subscribers", "20", env=bus.env)  # fmt: skip
        assert play.popen.wait(90) == 0, play.log()
        json_dets = [Detection.model_validate_json(sofia_dets.get(timeout=30)) for _ in range(N_FRAMES)]
    ros_dets = [p.next("detections", timeout=30) for _ in range(N_FRAMES)]
    truth_frames = truth["frames"]
    assert [d["stamp_ns"] for d in ros_dets] == [f["stamp_ns"] for f in truth_frames]
    for ros, js, tf in zip(ros_dets, json_dets, truth_frames, strict=True):
        assert ros["stamp_ns"] == js.stamp_ns and ros["frame_id"] == js.frame_id == "panda_link0"
        assert len(ros["items"]) == len(js.objects) == len(tf["objects"])
        for item, obj in zip(ros["items"], js.objects, strict=True):
            colour = "red" if obj.allowed else "not_red"
            assert item["class_id"] == f"{obj.field[0]},{obj.field[1]}/{colour}"
            assert np.allclose(item["center"], obj.center) and np.allclose(item["size"], obj.extents)
            assert item["score"] == pytest.approx(obj.confidence)
            truth_obj = min(tf["objects"], key=lambda o: np.linalg.norm(np.array(o["center"]) - obj.center))
            assert np.linalg.norm(np.array(item["center"]) - truth_obj["center"]) < 0.008
    assert "Traceback" not in bridge.log() and calibrator.popen.poll() is None
