"""What an error echoes is capped, and so is what a key accepts: a 1.68 MB JSON of 100,000 unknown
keys gets a short error naming the limit, never an 18 MB reply; a validation error of that size
is summarised; log lines are clipped."""

from __future__ import annotations

import json
import logging
import sys

import pytest
import zenoh
from sofia_runtime import zenoh_config
from sofia_runtime.client import query
from sofia_runtime.limits import ECHO_CHARS, MESSAGE_CHARS, ClipFilter, clip, error_text, payload_limit
from sofia_runtime.service import reply_error
from sofia_schemas import Keys, pointcloud
from sofia_schemas.messages import ErrorReply, GripperCommand

from .conftest import Service

HUGE = json.dumps({"action": "open", **{f"unknown_{i}": i for i in range(100_000)}}).encode()
HUGER = json.dumps({f"unknown_{i}": i for i in range(200_000)}).encode()  # beyond the detector's 4 MB


def _error(replies: list[zenoh.Reply]) -> tuple[ErrorReply, int]:
    (reply,) = replies
    assert reply.err is not None, "expected an error reply"
    raw = reply.err.payload.to_bytes()
    return ErrorReply.model_validate_json(raw), len(raw)


def test_clip_keeps_the_start_and_counts_the_rest() -> None:
    assert clip("x" * 10) == "x" * 10
    assert clip("a" * 1000) == "a" * ECHO_CHARS + f"… ({1000 - ECHO_CHARS} more characters)"
    assert clip(b"\x00" * 300).startswith("b'\\x00")


def test_payload_limits_per_key_and_configurable() -> None:
    assert payload_limit("sofia/panda/points", env={}) == 64 << 20
    assert payload_limit("sofia/panda/gripper/command", env={}) == 256 * 1024
    env = {"SOFIA_PAYLOAD_LIMITS": "sofia/*/gripper/command=4096, sofia/**=1e6"}
    assert payload_limit("sofia/panda/gripper/command", env=env) == 4096
    assert payload_limit("sofia/panda/points", env=env) == 1_000_000
    with pytest.raises(ValueError, match="is not KEYEXPR=BYTES"):
        payload_limit("sofia/panda/points", env={"SOFIA_PAYLOAD_LIMITS": "sofia/**=lots"})


def test_an_oversized_query_gets_a_short_error_naming_the_limit(detector: Service, module_robot: str) -> None:
    with zenoh.open(zenoh_config()) as session:
        err, size = _error(query(session, Keys(module_robot).detect, HUGER, timeout=30))
    assert err.error == "PayloadTooLarge"
    assert f"has {len(HUGER)} bytes, more than its limit of 4000000 bytes" in err.message
    assert size < 1000
    # the service keeps serving: a cloud under the limit is detected
    cloud = pointcloud.encode_points(pointcloud.np.zeros((100, 3)), stamp_ns=1, frame_id="panda_link0")
    with zenoh.open(zenoh_config()) as session:
        replies = query(session, Keys(module_robot).detect, bytes(cloud), timeout=30)
    assert replies and (
        replies[0].ok is not None or b"PayloadTooLarge" not in replies[0].err.payload.to_bytes()
    )
    assert max(len(line) for line in detector.log().splitlines()) < MESSAGE_CHARS + 200


def test_a_huge_validation_error_is_summarised_over_zenoh(robot_id: str) -> None:
    """A queryable replying with reply_error to 100,000 unknown keys: the reply stays short."""
    key = f"sofia/{robot_id}/gripper/command"

    def answer(q: zenoh.Query) -> None:
        try:
            GripperCommand.model_validate_json(q.payload.to_bytes() if q.payload else b"")
        except ValueError as e:
            reply_error(q, e)

    with zenoh.open(zenoh_config()) as session:
        session.declare_queryable(key, answer)
        err, size = _error(query(session, key, HUGE, timeout=30))
    assert err.error == "ValidationError"
    assert err.message.startswith("100000 validation errors for GripperCommand: unknown_0: Extra inputs")
    assert err.message.endswith("; and 99997 more")
    assert size < 2 * MESSAGE_CHARS


def test_log_records_are_clipped() -> None:
    handler = logging.StreamHandler()
    handler.addFilter(ClipFilter())
    record = logging.LogRecord("t", logging.WARNING, __file__, 1, "refused %s", (HUGE.decode(),), None)
    assert handler.filter(record)
    assert len(record.getMessage()) <= MESSAGE_CHARS + 40
    try:
        raise ValueError(HUGE.decode())
    except ValueError:
        record = logging.LogRecord("t", logging.ERROR, __file__, 1, "failed", None, sys.exc_info())
    handler.filter(record)
    assert record.exc_text is not None and len(record.exc_text) < 9000
    assert error_text(ValueError("y" * 10_000)).endswith("(8000 more characters)")


def test_the_calibrator_drops_oversized_blobs_and_poses(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """The calibrator's subscribers apply the same limits as the queryables: a 1 MB "blob" is
    dropped, counted and named in the log, and never reaches the sample store."""
    import os
    import time

    from sofia_schemas.messages import ServiceStatus

    from .conftest import Service

    robot = "c" + os.urandom(5).hex()
    env = dict(os.environ, SOFIA_ROBOT=robot, PYTHONUNBUFFERED="1")
    service = Service(["calibrator", "serve", "--state-dir", str(tmp_path)], env, tmp_path / "calibrator.log")
    try:
        service.wait_for_log("calibrator ready")
        keys = Keys(robot)
        with zenoh.open(zenoh_config()) as session:
            query(session, keys.status("calibrator"), timeout=30)  # discovered
            session.put(
                keys.blob, b"{" + b" " * (1 << 20) + b"}", congestion_control=zenoh.CongestionControl.BLOCK
            )
            service.wait_for_log("blob dropped: payload on", timeout=30)
            time.sleep(1.5)  # the next status publication
            (reply,) = query(session, keys.status("calibrator"), timeout=30)
        assert reply.ok is not None
        status = ServiceStatus.model_validate_json(reply.ok.payload.to_bytes())
        assert status.counters["dropped_blobs"] >= 1 and status.counters["samples"] == 0
    finally:
        service.stop()
