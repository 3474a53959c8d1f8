"""Top-down picks: flange pointing down, fingers across the width, fingertips at the centre."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from sofia_detector.pick import PickParams, Picks, first_pick, pick_target
from sofia_schemas.messages import DetectedObject, Detection
from sofia_schemas.transforms import quat_xyzw_to_matrix


def _obj(
    yaw: float = 0.3,
    extents=(0.08, 0.04, 0.05),
    allowed: bool = True,
    center=(0.5, 0.1, 0.025),
    confidence: float = 1.0,
) -> DetectedObject:  # type: ignore[no-untyped-def]
    return DetectedObject(
        center=center, centroid=center, extents=extents, yaw=yaw, field=(0, 0) if allowed else (0, 1),
        allowed=allowed, n_points=500, confidence=confidence,
    )  # fmt: skip


@given(yaw=st.floats(-np.pi / 2, np.pi / 2), length=st.floats(0.03, 0.1), width=st.floats(0.03, 0.1))
def test_pick_geometry(yaw: float, length: float, width: float) -> None:
    obj = _obj(yaw, (max(length, width), min(length, width), 0.05))
    p = pick_target(obj, stamp_ns=7)
    R = quat_xyzw_to_matrix(np.array(p.rotation_xyzw))
    assert np.linalg.det(R) == pytest.approx(1.0)
    assert np.allclose(R[:, 2], [0, 0, -1], atol=1e-9)  # flange z points down
    length_axis = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    assert abs(np.dot(R[:, 1], length_axis)) < 1e-9  # fingers close along flange y, across the width
    fingertips = np.array(p.grasp_translation) + R[:, 2] * 0.20
    assert np.allclose(fingertips, obj.center, atol=1e-9)
    assert np.allclose(np.array(p.pregrasp_translation) - p.grasp_translation, [0, 0, 0.10])
    assert p.opening_mm == pytest.approx(min(length, width) * 1e3 + 20.0, abs=0.01)
    assert p.stamp_ns == 7 and p.object_center == obj.center


def test_pick_params() -> None:
    p = pick_target(
        _obj(),
        0,
        params=PickParams(fingertip_offset=0.15, pregrasp_height=0.2, margin_mm=5, max_opening_mm=30),
    )
    assert p.grasp_translation[2] == pytest.approx(0.025 + 0.15)
    assert p.pregrasp_translation[2] == pytest.approx(0.025 + 0.35)
    assert p.opening_mm == 30.0


def test_first_pick_takes_the_first_allowed_object() -> None:
    det = Detection(
        stamp_ns=5,
        frame_id="panda_link0",
        status="ok",
        objects=[_obj(allowed=False, center=(0.4, 0, 0.02)), _obj(center=(0.6, 0, 0.02))],
    )
    p = first_pick(det)
    assert p is not None and p.object_center == (0.6, 0.0, 0.02) and p.stamp_ns == 5
    assert first_pick(det.model_copy(update={"objects": det.objects[:1]})) is None


def test_objects_whose_centre_is_not_trusted_get_no_pick() -> None:
    """A truncated object (confidence below 0.5: its centre is that of its visible part) on a red
    field is passed over for the next trusted one, and alone it gives no pick."""
    cut = _obj(center=(0.4, 0, 0.02), confidence=0.31)
    whole = _obj(center=(0.6, 0, 0.02), confidence=0.93)
    det = Detection(stamp_ns=5, frame_id="panda_link0", status="ok", objects=[cut, whole])
    p = first_pick(det)
    assert p is not None and p.object_center == whole.center
    alone = det.model_copy(update={"objects": [cut]})
    assert first_pick(alone) is None
    at_floor = det.model_copy(update={"objects": [_obj(confidence=0.5)]})
    assert first_pick(at_floor) is not None  # the floor itself is trusted
    p = first_pick(alone, PickParams(min_confidence=0.3))  # the user's own floor
    assert p is not None and p.object_center == cut.center


def test_picks_count_and_log_a_run_of_withheld_picks_once(caplog: pytest.LogCaptureFixture) -> None:
    cut = Detection(stamp_ns=1, frame_id="panda_link0", status="ok", objects=[_obj(confidence=0.3)])
    whole = cut.model_copy(update={"objects": [_obj(confidence=0.95)]})
    off_red = cut.model_copy(update={"objects": [_obj(allowed=False, confidence=0.3)]})
    picks = Picks(PickParams())
    with caplog.at_level(logging.INFO, logger="sofia.detector"):
        got = [picks.of(d, "sofia/panda/points") for d in (cut, cut, cut, whole, off_red, cut)]
    assert [p is not None for p in got] == [False, False, False, True, False, False]
    assert picks.published == 1 and picks.withheld == 4  # the cloud without red objects is neither
    logged = [r.getMessage() for r in caplog.records if "no pick target" in r.getMessage()]
    assert len(logged) == 2 and "[0.3]" in logged[0] and "below 0.50" in logged[0]
