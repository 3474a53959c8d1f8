"""A ROS 2 service request the bridge cannot serve is answered in its response (``success`` false,
``message`` saying why), never with a Zenoh error reply, which rmw_zenoh's client drops; the reply's
attachment is in the request's form (compact, or keyed as rmw_zenoh 0.2.0-0.2.3 sends it)."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from typing import Any

import pytest
import zenoh
from sofia_runtime.ros2.bridge import JSON_QUERY
from sofia_runtime.ros2.rmw import Attachment, data_key
from sofia_schemas.ros2.typesupport import decode

from ..conftest import Proc
from .conftest import Bus


@pytest.mark.parametrize("keyed", [False, True])
def test_bad_request_gets_a_response_saying_why(
    sofia_proc: Callable[..., Proc], bus: Bus, robot_id: str, keyed: bool
) -> None:
    bridge = sofia_proc("ros2", "serve", env={**bus.env, "ROS_DOMAIN_ID": "0"})
    bridge.wait_for_log("ros2 ready", timeout=60)
    key = data_key(0, f"/sofia/{robot_id}/calibrator/solve", JSON_QUERY)
    request = Attachment(42, time.time_ns(), bytes(range(16)), keyed=keyed)
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{bus.port}"]))
    replies: list[Any] = []
    with zenoh.open(conf) as session:
        deadline = time.monotonic() + 30
        while not replies and time.monotonic() < deadline:  # until the bridge's service is discovered
            replies = list(
                session.get(key, payload=b"\x00\x01not cdr", attachment=request.encode(), timeout=10)
            )
    assert len(replies) == 1 and replies[0].ok is not None, [
        r.err and r.err.payload.to_bytes() for r in replies
    ]
    response = decode(replies[0].ok.payload.to_bytes(), f"{JSON_QUERY}_Response")
    assert response.success is False and f"not a {JSON_QUERY} request" in response.message, response.message
    att = Attachment.decode(replies[0].ok.attachment.to_bytes())
    assert (att.sequence_number, att.source_gid, att.keyed) == (42, request.source_gid, keyed)
    assert bridge.popen.poll() is None
