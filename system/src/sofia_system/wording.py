"""What the demo says about a detection or a transform, in sentences a newcomer can read."""

from __future__ import annotations

from datetime import UTC, datetime

import numpy as np
from sofia_schemas.messages import DetectedObject, Detection

MISSED_MM = float("inf")  # the "error" of an object that was there and not found (or found on an empty board)


def clock(stamp_ns: int) -> str:
    """A wall-clock stamp in nanoseconds as ``02:31:12 UTC``."""
    return datetime.fromtimestamp(stamp_ns / 1e9, UTC).strftime("%H:%M:%S UTC")


def transform_text(name: str) -> str:
    """The detector's name of the flange->camera transform it used, e.g. ``calibrator result
    1795397011438923260`` -> ``the calibrator's result of 02:31:12 UTC``."""
    head, _, stamp = name.rpartition(" ")
    if head == "calibrator result" and stamp.isdigit():
        return f"the calibrator's result of {clock(int(stamp))}"
    return name


def field_text(obj: DetectedObject) -> str:
    """``red field (2, 2)``: red fields are where objects are picked from."""
    if obj.field is None:
        return "no field (off the board's fields)"
    return f"{'red' if obj.allowed else 'non-red (not to pick)'} field {tuple(obj.field)}"


def describe_detection(det: Detection, truth_objects: list[dict] | None) -> tuple[str, float | None]:
    """(a sentence, the first object's centre error in mm against the truth).

    ``truth_objects``: the true objects of the same cloud (their ``center`` in the base frame,
    metres), or None when the recording has no truth for its stamp. The error is None when there
    is nothing to compare, :data:`MISSED_MM` when an object was missed or invented.
    """
    if truth_objects is None:
        return "no ground truth for this stamp", None
    truths = [np.asarray(o["center"], dtype=float) for o in truth_objects]
    if not det.objects:
        if truths:
            return f"MISSED: no object found, {len(truths)} on the board", MISSED_MM
        return "no object on the board (right: the board is empty)", None
    o = det.objects[0]
    c = o.center
    where = f"on {field_text(o)}, centre ({c[0]:.3f}, {c[1]:.3f}, {c[2]:.3f}) m"
    text = f"1 object {where}" if len(det.objects) == 1 else f"{len(det.objects)} objects, the first {where}"
    if not truths:
        return f"{text} (WRONG: the board is empty)", MISSED_MM
    err_mm = min(float(np.linalg.norm(np.asarray(c) - t)) for t in truths) * 1000
    return f"{text}, {err_mm:.1f} mm from the true centre", err_mm
