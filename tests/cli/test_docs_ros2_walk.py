"""Walking the ROS 2 page (docs/how-to/ros2.md) as a newcomer would: its first command (`sofia up
--ros2`) and its second (a recording looping onto the bus) run as written in the folder of the
offline walk, then a ROS 2 node using rmw_zenoh on the router's default endpoint, as step 3 points
it, lists SofIA's topics and receives the detections as ``vision_msgs/msg/Detection3DArray``.

The node is the zenoh-ros2-sdk peer of ``tests/ros2/peer.py`` (an rmw_zenoh implementation
independent of SofIA's, its own process, the message definitions given locally): no ROS
installation is needed, and SofIA is reached only through the router, as `ros2 topic echo` would.
"""

from __future__ import annotations

import json
import os
import queue
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import pytest
from sofia_schemas.ros2.typesupport import MSGS_DIR

from .test_docs_bus_walk import ROUTER_PORT, start, stop, wait_healthy, wait_port_free
from .test_docs_commands import ROOT, page_commands

PAGE = ROOT / "docs" / "how-to" / "ros2.md"
PEER = ROOT / "tests" / "ros2" / "peer.py"
FIRST_DETECTION_S = 90.0


def steps() -> list[list[str]]:
    """The page's first two `sofia` commands: the steps 1 and 2 it tells the reader to run."""
    return [argv[1:] for _, argv in page_commands(PAGE) if argv[0] == "sofia"][:2]


def test_the_ros2_page_has_the_steps_this_walk_runs() -> None:
    assert steps() == [["up", "--ros2"], ["replay", "play", "var/recordings/scenes.mcap", "--loop"]]
    text = PAGE.read_text()
    assert (
        "export RMW_IMPLEMENTATION=rmw_zenoh_cpp" in text
        and "ros2 topic echo /sofia/panda/detections" in text
    )


def peer_lines(proc: subprocess.Popen[bytes]) -> queue.Queue[dict[str, Any]]:
    lines: queue.Queue[dict[str, Any]] = queue.Queue()

    def read() -> None:
        assert proc.stdout is not None
        for raw in proc.stdout:
            if raw.strip().startswith(b"{"):
                lines.put(json.loads(raw))

    threading.Thread(target=read, daemon=True).start()
    return lines


def next_line(lines: queue.Queue[dict[str, Any]], key: str, timeout: float, log: Path) -> Any:
    """The next line of the node carrying ``key`` with a non-empty value (others are skipped)."""
    try:
        while True:
            line = lines.get(timeout=timeout)
            if line.get(key):
                return line[key]
    except queue.Empty:
        raise AssertionError(
            f"the ROS 2 node printed no {key!r} in {timeout} s:\n{log.read_text()[-2000:]}"
        ) from None


NODE_TRIES = 3


def end_node(node: subprocess.Popen[bytes]) -> None:
    """Close the node's stdin (it exits), kill it if it does not within 20 s."""
    assert node.stdin is not None
    node.stdin.close()
    try:
        node.wait(20)
    except subprocess.TimeoutExpired:
        node.kill()
        node.wait(5)


@pytest.mark.timeout(600)
def test_a_ros2_node_sees_the_detections_by_following_the_page(walk_dir: Path) -> None:
    up_argv, replay_argv = steps()
    wait_port_free()  # rmw_zenoh's default endpoint, tcp/localhost:7447, must be this `sofia up`'s router
    env = {k: v for k, v in os.environ.items() if not k.startswith("SOFIA_")} | {"PYTHONUNBUFFERED": "1"}
    up = start(walk_dir, env, *up_argv, log=walk_dir / "up-ros2.out")
    try:
        wait_healthy(walk_dir / "up-ros2.out", ("detector",))
        loop = start(walk_dir, env, *replay_argv, log=walk_dir / "loop-ros2.out")
        node_log = walk_dir / "ros2-node.log"
        # The page's independent peer (zenoh-ros2-sdk, a client of the router) does not find SofIA's graph in
        # every fresh session (rmw_zenoh's own default config does: tests/ros2/test_rmw_default_config.py); as a
        # user would, a node that lists nothing is started again, up to NODE_TRIES times.
        node: subprocess.Popen[bytes] | None = None
        try:
            for attempt in range(1, NODE_TRIES + 1):
                with node_log.open("ab") as err:
                    node = subprocess.Popen([sys.executable, str(PEER), "--port", str(ROUTER_PORT), "--robot", "panda",
                                             "--msgs", str(MSGS_DIR)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                            stderr=err)  # fmt: skip
                lines = peer_lines(node)
                graph = next_line(lines, "graph", 120.0, node_log)  # `ros2 topic list -t`
                if "/sofia/panda/detections" in graph["topics"] or attempt == NODE_TRIES:
                    break
                end_node(node)
            assert graph["topics"].get("/sofia/panda/detections") == ["vision_msgs/msg/Detection3DArray"], (
                graph
            )
            detections = next_line(lines, "detections", FIRST_DETECTION_S, node_log)  # `ros2 topic echo`
            while not detections["items"]:  # the recording has empty boards too: wait for an object
                detections = next_line(lines, "detections", FIRST_DETECTION_S, node_log)
            assert detections["frame_id"] == "panda_link0"
            assert all(len(d["center"]) == 3 and d["class_id"] for d in detections["items"]), detections
        finally:
            if node is not None:
                end_node(node)
            stop(loop, "replay play --loop", walk_dir / "loop-ros2.out")
    finally:
        stop(up, "sofia up --ros2", walk_dir / "up-ros2.out")
