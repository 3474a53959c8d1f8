"""The calibrator's bounds, through the running service: a maximum number of samples (refused
beyond, named), ``samples`` paged, a failing solve answered with a named error (never a validation
error of the result's model) and the status degraded while solves fail."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from sofia_calibrator.fitting.simulate import make_problem
from sofia_calibrator.online import make_sample
from sofia_schemas.keys import Keys
from sofia_schemas.messages.calibration import CalibrationSample

from ..conftest import query_json

T0_NS = 1_700_000_000_000_000_000


def scrambled_depths(n: int) -> list[CalibrationSample]:
    """Samples whose blob depths are noise: the best depth scale of the fit is negative."""
    pr = make_problem(n, np.random.default_rng(0))
    depths = np.random.default_rng(0).uniform(0.05, 2.0, n)
    p_cam = np.column_stack([pr.p_cam[:, :2], depths])
    return [make_sample(T0_NS + k, p_cam[k], pr.T_base_flange[k]) for k in range(n)]


def test_max_samples_paging_and_failed_solves(sofia_proc, session, robot_id: str, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    keys = Keys(robot_id)
    proc = sofia_proc("calibrator", "serve", "--state-dir", str(tmp_path / "state"), "--max-samples", "25")
    proc.wait_for_log("calibrator ready", timeout=40)
    bad = scrambled_depths(25)
    for s in bad[:20]:
        ok, body = query_json(session, keys.calibrator_op("add"), s.to_json_bytes())
        assert ok, body

    ok, body = query_json(session, keys.calibrator_op("result"))  # solves the 20 first
    assert not ok and body["error"] == "InputMismatch" and "solve with 20 samples failed" in body["message"]
    assert "the fitted depth_scale came out -" in body["message"] and "not a scale" in body["message"], body
    ok, body = query_json(session, keys.calibrator_op("solve"))
    assert not ok and body["error"] == "SolveFailed" and "ValidationError" not in body["message"], body
    ok, status = query_json(session, keys.status("calibrator"))
    assert status["state"] == "degraded" and "solve with 20 samples failed" in status["detail"], status
    assert status["counters"]["solve_failures"] >= 2

    for s in bad[20:]:
        assert query_json(session, keys.calibrator_op("add"), s.to_json_bytes())[0]
    ok, body = query_json(session, keys.calibrator_op("add"), bad[0].to_json_bytes())
    assert not ok and body["error"] == "TooManySamples" and "maximum of 25 samples" in body["message"], body
    ok, status = query_json(session, keys.status("calibrator"))
    assert status["counters"]["samples"] == 25 and status["counters"]["refused_full"] == 1

    ok, body = query_json(session, keys.calibrator_op("samples"), json.dumps({"limit": 10}))
    assert ok and [s["sample_id"] for s in body["samples"]] == list(range(10))
    ok, body = query_json(session, keys.calibrator_op("samples"), json.dumps({"after_id": 19, "limit": 10}))
    assert ok and [s["sample_id"] for s in body["samples"]] == list(range(20, 25))
    ok, body = query_json(session, keys.calibrator_op("samples"), json.dumps({"limit": 100000}))
    assert not ok and "limit" in body["message"] and "500" in body["message"], body

    ok, body = query_json(session, keys.calibrator_op("reset"))  # solves stop failing: status ok again
    assert ok and body["samples"] == []
    good = make_problem(12, np.random.default_rng(5))
    for k in range(12):
        sample = make_sample(T0_NS + k, good.p_cam[k], good.T_base_flange[k])
        assert query_json(session, keys.calibrator_op("add"), sample.to_json_bytes())[0]
    ok, body = query_json(session, keys.calibrator_op("result"))
    assert ok and body["n_samples"] == 12
    ok, status = query_json(session, keys.status("calibrator"))
    assert "failed" not in status["detail"], status
    assert proc.stop() == 0
