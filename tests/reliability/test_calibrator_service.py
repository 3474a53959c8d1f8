"""``sofia calibrator serve`` as a separate process over Zenoh, importing a damaged sample log of an
older version, under refused and failed operations, a blob flood with queries, and bursts of
samples."""

from __future__ import annotations

import json
import resource
import threading
import time
from pathlib import Path

import numpy as np
import zenoh
from sofia_calibrator.fitting.simulate import make_problem
from sofia_calibrator.online import make_sample
from sofia_calibrator.samples.log import encode
from sofia_runtime import client
from sofia_runtime.zenoh_config import open_session
from sofia_schemas.keys import Keys
from sofia_schemas.messages import BlobObservation, FlangePose
from sofia_schemas.messages.calibration import CalibrationSample
from sofia_schemas.rosmsg import encode_blob, encode_flange_pose

from ..conftest import query_json

T0_NS = 1_700_000_000_000_000_000


def samples(n: int, seed: int = 3) -> list[CalibrationSample]:
    """``n`` plausible samples of a simulated calibration."""
    pr = make_problem(n, np.random.default_rng(seed))
    return [make_sample(T0_NS + k, pr.p_cam[k], pr.T_base_flange[k]) for k in range(n)]


def start(sofia_proc, session: zenoh.Session, keys: Keys, state: Path):  # type: ignore[no-untyped-def]
    proc = sofia_proc("calibrator", "serve", "--state-dir", str(state))
    proc.wait_for_log("calibrator ready", timeout=40)
    assert client.query(session, keys.calibrator_op("samples"), timeout=40.0), "calibrator not reachable"
    return proc


def ids(session: zenoh.Session, keys: Keys) -> list[int]:
    ok, body = query_json(session, keys.calibrator_op("samples"))
    assert ok, body
    return [s["sample_id"] for s in body["samples"]]


def add(session: zenoh.Session, keys: Keys, sample: CalibrationSample, **change: object) -> tuple[bool, dict]:  # type: ignore[type-arg]
    s = sample.model_dump(mode="json") | change
    return query_json(session, keys.calibrator_op("add"), json.dumps(s))


def write_log(state: Path, n: int) -> None:
    """A log of ``n`` samples in one write (as the service writes them, one checksummed line each)."""
    state.mkdir(parents=True, exist_ok=True)
    lines = [encode({"op": "add", "sample": s.model_dump(mode="json") | {"sample_id": k}})
             for k, s in enumerate(samples(n))]  # fmt: skip
    (state / "samples.jsonl").write_bytes(b"".join(lines))


def test_damaged_log_loads_the_rest_reports_it_and_keeps_new_samples(
    sofia_proc, session, robot_id, tmp_path
) -> None:  # type: ignore[no-untyped-def]
    keys, state = Keys(robot_id), tmp_path / "state"
    write_log(state, 6)
    log_path = state / "samples.jsonl"
    with log_path.open("ab") as f:  # remove 1, add 6
        f.write(encode({"op": "remove", "sample_ids": [1]}))
        f.write(
            encode({"op": "add", "sample": samples(1, seed=4)[0].model_dump(mode="json") | {"sample_id": 6}})
        )
    lines = log_path.read_bytes().splitlines(keepends=True)
    lines[6] = lines[6].replace(b"[1]", b"[2]")  # the remove: damaged, still valid JSON
    lines.insert(3, b'{"op": "add", "sample": {"p_cam": [0.1, \xff]}}\n')  # not UTF-8, no sample_id
    log_path.write_bytes(b"".join(lines)[:-60])  # and a torn last record (sample 6)

    proc = start(sofia_proc, session, keys, state)
    assert ids(session, keys) == [0, 1, 2, 3, 4, 5]  # the removed sample is back: status says so
    ok, status = query_json(session, keys.status("calibrator"))
    assert ok and status["state"] == "degraded" and "samples may be inconsistent" in status["detail"]
    assert status["counters"]["damaged_lines"] == 2 and status["counters"]["torn_bytes"] > 0
    assert status["info"]["samples_consistent"] is False
    assert "samples.jsonl:4 skipped" in proc.log() and "samples.jsonl:8 skipped" in proc.log()
    assert (state / "samples.jsonl.torn").is_file() and (state / "samples.jsonl.damaged").is_file()
    assert (state / "samples.jsonl.imported").is_file() and (state / "samples.db").is_file()

    acked = [add(session, keys, s) for s in samples(9)[7:]]
    assert all(ok for ok, _ in acked), acked
    proc.kill()
    proc2 = start(sofia_proc, session, keys, state)
    assert ids(session, keys) == [0, 1, 2, 3, 4, 5, *(b["samples"][0]["sample_id"] for _, b in acked)]
    assert [b["samples"][0]["sample_id"] for _, b in acked] == [6, 7]  # 6 was torn: never acknowledged
    ok, status = query_json(session, keys.status("calibrator"))  # the import's findings survive restarts
    assert ok and status["info"]["samples_consistent"] is False and status["state"] == "degraded"
    ok, body = query_json(session, keys.calibrator_op("reset"))  # the operator starts over
    assert ok and body["samples"] == []
    ok, status = query_json(session, keys.status("calibrator"))
    assert ok and status["info"]["samples_consistent"] is True and status["counters"]["torn_bytes"] == 0
    assert status["state"] == "ok", status
    assert proc2.stop() == 0


def test_unopenable_database_stops_the_start_naming_the_file(sofia_proc, robot_id, tmp_path) -> None:  # type: ignore[no-untyped-def]
    (tmp_path / "state" / "samples.db").mkdir(parents=True)
    proc = sofia_proc("calibrator", "serve", "--state-dir", str(tmp_path / "state"))
    assert proc.popen.wait(60) == 2
    assert f"{tmp_path / 'state' / 'samples.db'}: cannot open the sample database" in proc.log()


def test_refused_operations_are_absent_and_acknowledged_ones_durable(
    sofia_proc, session, robot_id, tmp_path
) -> None:  # type: ignore[no-untyped-def]
    keys, state = Keys(robot_id), tmp_path / "state"
    write_log(state, 40)  # imported on the first start
    proc = start(sofia_proc, session, keys, state)

    for change, reason in (({"rotation_xyzw": [0, 0, 0, 0]}, "unit quaternion"),
                           ({"translation": [1e300, 0, 0]}, "more than 5.0 m"),
                           ({"p_cam": [0, 0, 1e20]}, "more than 10.0 m"),
                           ({"stamp_ns": 10**400}, "401 digits")):  # fmt: skip
        ok, body = add(session, keys, samples(41)[40], **change)
        assert not ok and body["error"] == "ImplausibleSample" and reason in body["message"], body
    ok, body = query_json(session, keys.calibrator_op("remove"), json.dumps({"sample_ids": [0, 999999]}))
    assert not ok and "no sample with id 999999: nothing removed" in body["message"], body
    assert ids(session, keys) == list(range(40))

    db = state / "samples.db"
    size = db.stat().st_size  # a full disk: no WAL frame (4 kB) can be written any more
    hard = resource.getrlimit(resource.RLIMIT_FSIZE)[1]
    resource.prlimit(proc.popen.pid, resource.RLIMIT_FSIZE, (2000, hard))
    ok, body = add(session, keys, samples(41)[40])
    assert not ok and "add failed, nothing written" in body["message"], body
    ok, body = query_json(session, keys.calibrator_op("remove"), json.dumps({"sample_ids": [3]}))
    assert not ok and "remove failed, nothing written" in body["message"]
    ok, status = query_json(session, keys.status("calibrator"))  # shown while the disk is full
    assert ok and status["state"] == "degraded" and "sample store not writable" in status["detail"], status
    resource.prlimit(proc.popen.pid, resource.RLIMIT_FSIZE, (hard, hard))
    assert db.stat().st_size == size
    ok, body = add(session, keys, samples(42)[41])
    assert ok and body["samples"][0]["sample_id"] == 40
    ok, status = query_json(session, keys.status("calibrator"))
    assert ok and status["counters"]["write_errors"] == 2 and "not writable" not in status["detail"]

    proc.kill()
    proc2 = start(sofia_proc, session, keys, state)
    assert ids(session, keys) == list(range(41))  # exactly what was acknowledged
    ok, status = query_json(session, keys.status("calibrator"))
    assert status["counters"]["damaged_lines"] == 0 and status["counters"]["torn_bytes"] == 0
    assert proc2.stop() == 0


def test_burst_is_solved_once_and_queries_are_answered_during_a_blob_flood(
    sofia_proc, session, robot_id, tmp_path
) -> None:  # type: ignore[no-untyped-def]
    keys, state = Keys(robot_id), tmp_path / "state"
    write_log(state, 100)
    t_start = time.monotonic()
    proc = start(sofia_proc, session, keys, state)
    proc.wait_for_log("calibrator: solved with 100 samples", timeout=60)
    print(f"started and solved in {time.monotonic() - t_start:.1f} s")

    t0 = time.monotonic()  # a burst of 20 adds, one after the other: solved once the burst is over
    for sample in samples(120)[100:]:  # the same camera as the first 100
        ok, body = add(session, keys, sample)
        assert ok, body
    per_add_ms = (time.monotonic() - t0) / 20 * 1e3
    ok, body = query_json(session, keys.calibrator_op("result"))  # the result of all 120 samples
    assert ok and body["n_samples"] == 120, body
    print(f"time per add at 100 samples: {per_add_ms:.1f} ms")
    assert proc.log().count("calibrator: solved with 1") <= 6, proc.log()[-3000:]  # one per add was 21

    pr = make_problem(125, np.random.default_rng(3))  # the same camera again
    for k in range(120, 125):  # a burst of blobs with their poses: solved once more, not five times
        stamp = T0_NS + k * 10**9
        for dt in (-(10**8), 0, 10**8):
            session.put(
                keys.flange_pose, encode_flange_pose(FlangePose.from_matrix(pr.T_base_flange[k], stamp + dt))
            )
        session.put(keys.blob, encode_blob(BlobObservation(stamp_ns=stamp, position=tuple(pr.p_cam[k]))))  # type: ignore[arg-type]
    session.put(
        keys.flange_pose, encode_flange_pose(FlangePose.from_matrix(pr.T_base_flange[124], stamp + 10**9))
    )
    proc.wait_for_log("calibrator: solved with 125 samples", timeout=60)
    assert proc.log().count("calibrator: solved with 12") <= 3, proc.log()[-3000:]

    flooding = threading.Event()

    def flood() -> None:
        blob = encode_blob(BlobObservation(stamp_ns=T0_NS // 2, position=(0.0, 0.0, 0.5)))  # no pose near
        with open_session() as s:
            while not flooding.is_set():
                for _ in range(100):
                    s.put(keys.blob, blob)
                time.sleep(0.001)  # lets the querying thread run: about 50,000 blobs/s still

    flooder = threading.Thread(target=flood, daemon=True)
    flooder.start()
    t_flood = time.monotonic()
    try:  # 300 queries in flight while blobs fill the event queue: each gets a reply
        pending = [session.get(keys.calibrator_op("samples"), timeout=30) for _ in range(300)]
        replies = [list(p) for p in pending]
        deadline = time.monotonic() + 20.0  # flood on until the event queue has overflowed
        while (
            time.monotonic() < deadline
            and not query_json(session, keys.status("calibrator"))[1]["counters"]["dropped_blobs"]
        ):
            time.sleep(0.2)
    finally:
        flooding.set()
        flooder.join(10)
    assert all(len(r) == 1 for r in replies), [len(r) for r in replies]  # never silence
    busy = [json.loads(r[0].err.payload.to_bytes()) for r in replies if r[0].err is not None]
    assert busy and all(b["error"] == "CalibratorBusy" and "busy, retry" in b["message"] for b in busy)
    ok, status = query_json(session, keys.status("calibrator"))
    c = status["counters"]
    assert ok and c["dropped_queries"] == len(busy) and c["dropped_blobs"] > 0, c
    print(f"blob flood of {time.monotonic() - t_flood:.1f} s: {c['dropped_blobs']} blobs dropped, "
          f"{len(busy)} of 300 queries answered busy")  # fmt: skip
    assert proc.stop() == 0
