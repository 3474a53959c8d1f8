"""The responses of service requests the bridge cannot serve: ROS services answer errors in their
response (``success`` false, ``message``); rmw_zenoh's client drops Zenoh error replies."""

from __future__ import annotations

from collections.abc import Callable

import zenoh
from sofia_schemas.ros2 import convert as cv
from sofia_schemas.ros2.typesupport import encode

from .rmw import Attachment

JSON_QUERY = "sofia_msgs/srv/JsonQuery"
# (query, its attachment, request CDR, handler CDR -> CDR, error message -> response CDR)
Request = tuple[zenoh.Query, Attachment, bytes, Callable[[bytes], bytes], Callable[[str], bytes]]


def detect_failure(message: str) -> bytes:
    """The ``DetectObject`` response of a request that failed: ``success`` false, ``message``."""
    return encode(cv.detect_response(None, message), f"{cv.DETECT_OBJECT}_Response")


def json_query_failure(message: str) -> bytes:
    """The ``JsonQuery`` response of a request that failed: ``success`` false, ``message``."""
    return encode(
        cv.new(f"{JSON_QUERY}_Response", success=False, message=message, json=""), f"{JSON_QUERY}_Response"
    )
