"""The calibrator's sample store under SIGKILL and damage, through the running service.

Run: .venv/bin/python bench/bench_durability.py [--cycles 20]

Each cycle starts ``sofia calibrator serve`` (its own process) on the same state directory, sends
``add`` and ``remove`` queries one after the other from this process, and SIGKILLs the service at
a random moment (0.3 to 1.5 s in, from a timer: in the middle of an operation; the one cut
has no reply and counts as refused). After each restart the samples are compared with what was
acknowledged: ``lost`` (an acknowledged add missing), ``resurrected`` (an acknowledged remove
back). Then the database is cut short, and then overwritten mid-file: whether the service starts,
reports it and keeps what it could read. RSS of the service: at its start, peak, before the last kill.
Baseline in the same run: the time per acknowledged add of the store (SQLite, WAL,
synchronous=FULL) against a bare append + fsync of the same bytes (the cost floor of a durable log).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

SOFIA = str(Path(sys.executable).with_name("sofia"))
T0_NS = 1_700_000_000_000_000_000


def start(state: Path, env: dict[str, str], log: Path) -> subprocess.Popen[bytes]:
    with open(log, "ab") as f:
        return subprocess.Popen([SOFIA, "calibrator", "serve", "--state-dir", str(state)], env=env,
                                stdout=f, stderr=subprocess.STDOUT)  # fmt: skip


def store_vs_fsync(tmp: Path, n: int = 200) -> tuple[float, float]:
    """(ms per add of the store, ms per append + fsync of the same JSON)."""
    from sofia_calibrator.fitting.simulate import make_problem
    from sofia_calibrator.online import make_sample
    from sofia_calibrator.samples.store import SampleStore

    pr = make_problem(n, np.random.default_rng(1))
    samples = [make_sample(T0_NS + k, pr.p_cam[k], pr.T_base_flange[k]) for k in range(n)]
    store = SampleStore(tmp / "store")
    t0 = time.perf_counter()
    for s in samples:
        store.add(s)
    ours = (time.perf_counter() - t0) / n * 1e3
    store.close()
    fd = os.open(tmp / "plain.jsonl", os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    t0 = time.perf_counter()
    for s in samples:
        os.write(fd, s.model_dump_json().encode() + b"\n")
        os.fsync(fd)
    base = (time.perf_counter() - t0) / n * 1e3
    os.close(fd)
    return ours, base


def main() -> int:
    from bench_fuzz import own_bus
    from sofia_calibrator.fitting.simulate import make_problem
    from sofia_calibrator.online import make_sample
    from sofia_runtime.memory import rss_bytes
    from sofia_runtime.zenoh_config import open_session

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=20)
    a = ap.parse_args()
    keys, tmp, env = own_bus("durability")
    state, log = tmp / "state", tmp / "calibrator.log"
    pr = make_problem(50, np.random.default_rng(2))
    rng = random.Random(3)
    tried = refused = 0
    acked: set[int] = set()
    removed: set[int] = set()
    lost_total = resurrected_total = 0
    in_flight: set[int] = set()
    rss_start, rss_peak, rss_end = [], 0, 0
    with open_session() as session:

        def ask(op: str, payload: bytes, timeout: float = 5.0) -> dict | None:  # type: ignore[type-arg]
            replies = list(session.get(keys.calibrator_op(op), payload=payload, timeout=timeout))
            if not replies or replies[0].ok is None:
                return None
            return json.loads(replies[0].ok.payload.to_bytes())  # type: ignore[no-any-return]

        def stored() -> set[int] | None:
            deadline = time.monotonic() + 60
            while time.monotonic() < deadline:
                ids: set[int] = set()
                after = -1
                while (page := ask("samples", json.dumps({"after_id": after}).encode(), 2.0)) is not None:
                    ids |= {s["sample_id"] for s in page["samples"]}
                    if len(page["samples"]) < 500:
                        return ids
                    after = max(ids)
                time.sleep(0.2)
            return None

        for _ in range(a.cycles):
            proc = start(state, env, log)
            ids = stored()
            assert ids is not None, log.read_text()[-2000:]
            rss_start.append(rss_bytes(proc.pid))
            lost = (acked - removed - in_flight) - ids
            in_flight = set()
            back = ids & removed
            lost_total += len(lost)
            resurrected_total += len(back)
            removed |= (acked - removed) - ids  # gone: counted once
            killer = threading.Timer(rng.uniform(0.3, 1.5), proc.send_signal, (signal.SIGKILL,))
            killer.start()  # the kill comes in the middle of whatever the service is doing
            k = 0
            while proc.poll() is None:
                tried += 1
                if k % 3 == 2 and acked - removed:
                    victim = max(acked - removed)
                    in_flight = {victim}  # a remove cut by the kill may have committed
                    if ask("remove", json.dumps({"sample_ids": [victim]}).encode(), 2.0) is None:
                        refused += 1  # no reply: cut by the kill, it may have committed
                    else:
                        removed.add(victim)
                        in_flight = set()
                else:
                    s = make_sample(T0_NS + k, pr.p_cam[k % 50], pr.T_base_flange[k % 50])
                    body = ask("add", s.to_json_bytes(), 2.0)
                    if body is None:
                        refused += 1
                    else:
                        acked.add(body["samples"][0]["sample_id"])
                if proc.poll() is None:
                    rss_end = rss_bytes(proc.pid)
                    rss_peak = max(rss_peak, rss_end)
                k += 1
            killer.join()
        proc = start(state, env, log)
        ids = stored() or set()
        lost_total += len((acked - removed - in_flight) - ids)
        resurrected_total += len(ids & removed)
        proc.terminate()
        proc.wait(30)

        damage = []
        for kind in ("cut short", "overwritten mid-file"):
            db = state / "samples.db"
            data = bytearray(db.read_bytes())
            if kind == "cut short":
                del data[len(data) // 2 :]
            else:
                page = 4096 * (len(data) // 4096 // 2)
                data[page : page + 4096] = np.random.default_rng(4).bytes(4096)
            db.write_bytes(bytes(data))
            proc = start(state, env, log)
            after_ids = stored()
            status: dict = {}  # type: ignore[type-arg]
            for _ in range(6):  # a loaded host: the first status query may find no reply in 5 s
                replies = list(session.get(keys.status("calibrator"), timeout=5))
                if replies and replies[0].ok is not None:
                    status = json.loads(replies[0].ok.payload.to_bytes())
                    break
            damage.append((kind, after_ids is not None, status.get("state"), len(after_ids or ()),
                           status.get("detail", "")[:90]))  # fmt: skip
            proc.terminate()
            proc.wait(30)
    ours, base = store_vs_fsync(tmp)
    print(f"{a.cycles} SIGKILL cycles of sofia calibrator serve (adds and removes over Zenoh)\n")
    print("| tried | refused | acknowledged adds | acknowledged removes | lost | resurrected |")
    print("|---:|---:|---:|---:|---:|---:|")
    print(f"| {tried} | {refused} | {len(acked)} | {len(removed)} | {lost_total} | {resurrected_total} |")
    print(f"\nRSS of the calibrator: at start {np.median(rss_start) / 1e6:.0f} MB (median), peak "
          f"{rss_peak / 1e6:.0f} MB, before the last kill {rss_end / 1e6:.0f} MB\n")  # fmt: skip
    print("| damage | service up | state | samples kept | detail |")
    print("|---|---|---|---:|---|")
    for kind, up, st, n, detail in damage:
        print(f"| {kind} | {'yes' if up else 'no'} | {st} | {n} | {detail} |")
    print(f"\nper acknowledged add: store {ours:.2f} ms, bare append + fsync {base:.2f} ms "
          f"(ratio {ours / base:.2f}x)")  # fmt: skip
    shutil.rmtree(tmp, ignore_errors=True)
    return 1 if lost_total or resurrected_total else 0


if __name__ == "__main__":
    sys.exit(main())
