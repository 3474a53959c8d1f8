"""Stamps are checked: results, flange poses, blobs and samples stamped beyond the tolerance in the
future, and results published live with a stamp before the detector started, are refused and
counted (:class:`sofia_runtime.stamps.StampCheck`). The services run as their own processes."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import pytest
import zenoh
from sofia_runtime.stamps import FUTURE_TOLERANCE_NS, StampCheck, StampRefused
from sofia_schemas.keys import ENCODING_JSON, Keys
from sofia_schemas.messages import FlangePose, ServiceStatus
from sofia_schemas.messages.calibration import CalibrationSample
from sofia_schemas.rosmsg import encode_flange_pose

from ..conftest import Proc, first_reply, reply_err
from ..detector.test_service import _calibration_result

FAR_FUTURE_NS = 2**62  # year 2116


def status(session: zenoh.Session, keys: Keys, service: str) -> ServiceStatus:
    reply = first_reply(session, keys.status(service))
    assert reply.ok is not None
    return ServiceStatus.model_validate_json(reply.ok.payload.to_bytes())


def wait_counter(session: zenoh.Session, keys: Keys, service: str, name: str, value: int,
                 resend: Callable[[], None]) -> ServiceStatus:  # fmt: skip
    """Resend until ``counters[name] >= value`` (the first puts may precede the subscription)."""
    deadline = time.monotonic() + 20
    while (s := status(session, keys, service)).counters.get(name, 0) < value:
        assert time.monotonic() < deadline, f"{service} {name} = {s.counters.get(name)}: {s}"
        resend()
        time.sleep(0.2)
    return s


def test_stamp_check_window() -> None:
    now = 1_800_000_000_000_000_000
    check = StampCheck(start_ns=now - 10, clock=lambda: now)
    assert check.check("pose", now + FUTURE_TOLERANCE_NS) == now + FUTURE_TOLERANCE_NS
    with pytest.raises(StampRefused, match=r"result refused: stamp_ns 461168601842.*in the future"):
        check.check("result", FAR_FUTURE_NS)
    assert check.check("result", now - 11) == now - 11  # before the start: only refused when asked
    with pytest.raises(StampRefused, match="before this service started"):
        check.check("result", now - 11, since_start=True)
    assert check.counters == {"future_stamps": 1, "stamps_before_start": 1}


def test_detector_refuses_future_and_replayed_results(sofia_proc: Callable[..., Proc], session: zenoh.Session,
                                                      robot_id: str) -> None:  # fmt: skip
    keys = Keys(robot_id)
    proc = sofia_proc("detector", "serve")
    proc.wait_for_log("detector ready")
    future = _calibration_result(FAR_FUTURE_NS).to_json_bytes()
    s = wait_counter(session, keys, "detector", "future_stamps", 1,
                     lambda: session.put(keys.calibration_result, future, encoding=ENCODING_JSON))  # fmt: skip
    assert s.info["transform"] is None  # the 2**62 result pinned nothing
    genuine = _calibration_result(time.time_ns())
    session.put(keys.calibration_result, genuine.to_json_bytes(), encoding=ENCODING_JSON)
    proc.wait_for_log(f"using T_flange_cam from the calibrator (result {genuine.stamp_ns})")

    replayed = _calibration_result(genuine.stamp_ns - 3600 * 10**9).to_json_bytes()  # before the start
    s = wait_counter(session, keys, "detector", "stamps_before_start", 1,
                     lambda: session.put(keys.calibration_result, replayed, encoding=ENCODING_JSON))  # fmt: skip
    ahead_ns = (
        time.time_ns() + 3600 * 10**9
    )  # a pose's ROS stamp holds seconds in int32: 2**62 ns does not fit
    pose = encode_flange_pose(FlangePose(stamp_ns=ahead_ns, translation=(0.4, 0.0, 0.5),
                                         rotation_xyzw=(0.0, 0.0, 0.0, 1.0)))  # fmt: skip
    s = wait_counter(session, keys, "detector", "future_stamps", s.counters["future_stamps"] + 1,
                     lambda: session.put(keys.flange_pose, pose))  # fmt: skip
    assert s.info["transform"] == f"calibrator result {genuine.stamp_ns}"
    assert s.info["flange_poses"] == 0
    assert f"flange pose refused: stamp_ns {ahead_ns} is 3600 s in the future" in proc.log()


def test_calibrator_refuses_future_samples(sofia_proc: Callable[..., Proc], session: zenoh.Session,
                                           robot_id: str, tmp_path: Path) -> None:  # fmt: skip
    keys = Keys(robot_id)
    proc = sofia_proc("calibrator", "serve", "--state-dir", str(tmp_path / "state"))
    proc.wait_for_log("calibrator ready")
    sample = CalibrationSample(stamp_ns=FAR_FUTURE_NS, p_cam=(0.0, 0.0, 0.5), translation=(0.4, 0.0, 0.5),
                               rotation_xyzw=(0.0, 0.0, 0.0, 1.0))  # fmt: skip
    e = reply_err(first_reply(session, keys.calibrator_op("add"), sample.to_json_bytes()))
    assert e.error == "StampRefused" and "in the future" in e.message
    s = status(session, keys, "calibrator")
    assert s.counters["future_stamps"] == 1 and s.counters["samples"] == 0
