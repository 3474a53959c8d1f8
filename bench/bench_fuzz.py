"""Malformed payloads on every key of the running services (detector, calibrator, emulated gripper:
separate processes, default Zenoh settings, loopback only).

For each key, at least 200 payloads (``--per-key``) made from a valid message of that key: empty,
random bytes (up to 3 MB), cut, bytes flipped, trailing garbage, JSON of the wrong types, NaN and
1e999, integers of 400 digits, deep nesting, 100,000 unknown keys, non-UTF-8; CDR clouds with
overlapping fields and zero counts. Queries are counted as ok, error-replied or no reply (none
within 10 s); puts have no reply, so only whether the service survived shows. ``crashed``: the
service's process died during that key's batch. RSS of the service before and after the batch
(when back within 1.2x of the steady value, or after 8 s). Steady: a service's RSS before its
first batch, after valid traffic (a warm-up) and rest. The reference is the issue's campaign: the
services must answer every query (``no reply`` 0), never crash, and come back to their steady
memory.

    .venv/bin/python bench/bench_fuzz.py [--per-key 200]
"""

from __future__ import annotations

import argparse
import json
import os
import random
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import zenoh
from sofia_runtime import zenoh_config
from sofia_runtime.memory import rss_bytes
from sofia_schemas import Keys, pointcloud
from sofia_schemas.pointcloud import FLOAT32, FLOAT64, PointField

REPO = Path(__file__).resolve().parents[1]
SOFIA = str(Path(sys.executable).with_name("sofia"))
TIMEOUT_S = 10.0
SETTLE_S = 8.0  # after a batch, the longest wait for the memory to come back before it is read


def _cloud(n: int = 200, fields: tuple[PointField, ...] | None = None, point_step: int = 12) -> bytes:
    if fields is None:
        rng = np.random.default_rng(n)
        return bytes(pointcloud.encode_points(rng.normal(size=(n, 3)), stamp_ns=1, frame_id="panda_link0"))
    head = pointcloud._header_bytes(
        1, "panda_link0", 1, n, fields, point_step, point_step * n, point_step * n
    )
    return head + bytes(point_step * n) + b"\x01"


def templates(now_ns: int) -> dict[str, bytes]:
    """A valid payload per kind of key, the seed of its malformed ones."""
    pose = {"stamp_ns": now_ns, "translation": [0.4, 0.0, 0.5], "rotation_xyzw": [0, 0, 0, 1]}
    return {
        "cloud": _cloud(),
        "pose": json.dumps(pose).encode(),
        "blob": json.dumps({"stamp_ns": now_ns, "position": [0.0, 0.0, 0.5]}).encode(),
        "result": json.dumps({"stamp_ns": now_ns, "matrix": np.eye(4).tolist()}).encode(),
        "add": json.dumps(
            {
                "stamp_ns": now_ns,
                "p_cam": [0, 0, 0.5],
                "translation": [0.4, 0, 0.5],
                "rotation_xyzw": [0, 0, 0, 1],
            }
        ).encode(),
        "remove": json.dumps({"sample_ids": [1]}).encode(),
        "solve": json.dumps({}).encode(),
        "command": json.dumps({"action": "state"}).encode(),
        "none": b"{}",
    }


def _json_mutation(valid: bytes, r: random.Random) -> bytes:
    try:
        doc = json.loads(valid)
    except ValueError:
        doc = {}
    if not isinstance(doc, dict) or not doc:
        doc = {"x": 1}
    key = r.choice(list(doc))
    bad = r.choice([None, "NaN", float("nan"), float("inf"), -1e308, 10**400, "", [], {}, [[1e999]], True,
                    "x" * 5000, [0, 0, 0, 0], [1e20, 0, 0, 0], [1e300, 1e300, 1e300], -(2**70)])  # fmt: skip
    doc[key] = bad
    text = json.dumps(doc, allow_nan=True)
    return text.replace("Infinity", "1e999").encode() if r.random() < 0.5 else text.encode()


def malformed(valid: bytes, i: int, r: random.Random) -> bytes:
    """The ``i``-th malformed payload made from ``valid`` (20 kinds, in turn)."""
    kind = i % 20
    if kind == 0:
        return b""
    if kind == 1:
        return os.urandom(r.randint(1, 64))
    if kind == 2:
        return os.urandom(r.randint(1_000, 3_000_000))
    if kind == 3:
        return valid[: r.randrange(max(1, len(valid)))]
    if kind == 4:
        b = bytearray(valid)
        for _ in range(r.randint(1, 8)):
            b[r.randrange(len(b))] = r.randrange(256)
        return bytes(b)
    if kind == 5:
        return valid + os.urandom(r.choice([1, 4, 100, 1_000_000]))
    if kind in (6, 7, 8, 9, 10):
        return _json_mutation(valid, r)
    if kind == 11:
        return b"[" * 100_000 + b"]" * 100_000
    if kind == 12:
        return json.dumps({"action": "open", **{f"k{j}": j for j in range(100_000)}}).encode()
    if kind == 13:
        return b'{"stamp_ns": ' + b"9" * 400 + b"}"
    if kind == 14:
        return b'{"action": "\xff\xfe\xfa"}'
    if kind == 15:
        return json.dumps(r.choice([[], 1, "open", None, [1, 2, 3]])).encode()
    if kind == 16:
        f = (PointField("x", 0, FLOAT32), PointField("y", 0, FLOAT32), PointField("z", 0, FLOAT32))
        return _cloud(50, f)
    if kind == 17:
        f = (PointField("x", 0, FLOAT64), PointField("y", 4, FLOAT32), PointField("z", 8, FLOAT32, 0))
        return _cloud(50, f)
    if kind == 18:
        return b"\x00\x01\x00\x00" + os.urandom(r.randint(10, 5_000))
    return valid.replace(b"0", b"-", r.randint(1, 3))


def own_bus(name: str) -> tuple[Keys, Path, dict[str, str]]:
    """A robot id of its own (``name`` and random hex, so that runs do not meet), a new temporary
    folder, and the environment that puts the services started with it on that robot id."""
    robot = name + uuid.uuid4().hex[:6]
    tmp = Path(tempfile.mkdtemp(prefix=f"sofia-{name}-"))
    return Keys(robot), tmp, dict(os.environ, SOFIA_ROBOT=robot, PYTHONUNBUFFERED="1")


def start(name: str, args: list[str], env: dict[str, str], tmp: Path, ready: str) -> subprocess.Popen[bytes]:
    log = tmp / f"{name}.log"
    with open(log, "wb") as f:
        p = subprocess.Popen([SOFIA, *args], stdout=f, stderr=subprocess.STDOUT, env=env, cwd=REPO)
    deadline = time.monotonic() + 120
    while ready not in log.read_text(errors="replace"):
        if p.poll() is not None or time.monotonic() > deadline:
            raise SystemExit(f"{name} did not start:\n{log.read_text(errors='replace')[-3000:]}")
        time.sleep(0.1)
    return p


class PeakRss:
    """Samples the RSS of processes every 50 ms on its own thread; ``take(pid)`` gives the peak
    since the last take."""

    def __init__(self, pids: list[int]) -> None:
        self.peaks = dict.fromkeys(pids, 0)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.stop.wait(0.05):
            for pid in self.peaks:
                try:
                    self.peaks[pid] = max(self.peaks[pid], rss_bytes(pid))
                except (OSError, ValueError):
                    continue

    def take(self, pid: int) -> int:
        peak, self.peaks[pid] = self.peaks[pid], 0
        return peak


def warm_up(session: zenoh.Session, keys: Keys) -> None:
    """Valid traffic first, so the steady memory is that of services at work, not just started."""
    rng = np.random.default_rng(0)
    plane = rng.normal([0.5, 0.0, 0.0], [0.3, 0.3, 0.002], size=(480, 640, 3))
    cloud = bytes(pointcloud.encode_points(plane, stamp_ns=time.time_ns(), frame_id="panda_link0"))
    pub = session.declare_publisher(keys.points, congestion_control=zenoh.CongestionControl.BLOCK)
    for _ in range(20):
        pub.put(cloud)
        time.sleep(0.1)
    sample = templates(time.time_ns())["add"]
    for key, payload in ((keys.detect, cloud), (keys.gripper_command, b'{"action": "state"}'),
                         (keys.gripper_command, b'{"action": "nope"}'), (keys.calibrator_op("add"), sample),
                         (keys.calibrator_op("solve"), b""), (keys.calibrator_op("add"), b"{}")):  # fmt: skip
        for _ in range(5):
            list(session.get(key, payload=payload, timeout=TIMEOUT_S))
    list(session.get(keys.calibrator_op("reset"), timeout=TIMEOUT_S))
    time.sleep(3.0)


def fuzz_query(session: zenoh.Session, key: str, payloads: list[bytes]) -> dict[str, int]:
    def one(payload: bytes) -> str:
        replies = list(session.get(key, payload=payload, timeout=TIMEOUT_S))
        if not replies:
            return "no reply"
        return "ok" if replies[0].ok is not None else "error-replied"

    with ThreadPoolExecutor(4) as pool:
        outcomes = list(pool.map(one, payloads))
    return {k: outcomes.count(k) for k in ("ok", "error-replied", "no reply")}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--per-key", type=int, default=200)
    a = ap.parse_args()
    keys, tmp, env = own_bus("fuzz")
    procs = {
        "detector": start("detector", ["detector", "serve"], env, tmp, "detector ready"),
        "calibrator": start(
            "calibrator",
            ["calibrator", "serve", "--state-dir", str(tmp / "cal")],
            env,
            tmp,
            "calibrator ready",
        ),
        "gripper": start("gripper", ["gripper", "serve", "--emulate"], env, tmp, "ready"),
    }
    t = templates(time.time_ns())
    plan: list[tuple[str, str, str, bytes]] = [  # (service, kind, key, template)
        ("detector", "query", keys.detect, t["cloud"]),
        ("detector", "put", keys.points, t["cloud"]),
        ("detector", "put", keys.camera_points, t["cloud"]),
        ("detector", "put", keys.flange_pose, t["pose"]),
        ("detector", "put", keys.calibration_result, t["result"]),
        ("detector", "query", keys.status("detector"), t["none"]),
        ("calibrator", "put", keys.blob, t["blob"]),
        *(
            ("calibrator", "query", keys.calibrator_op(op), t.get(op, t["none"]))
            for op in ("add", "remove", "solve", "samples", "result", "save", "reset")
        ),
        ("calibrator", "query", keys.status("calibrator"), t["none"]),
        ("gripper", "query", keys.gripper_command, t["command"]),
        ("gripper", "query", keys.status("gripper"), t["none"]),
    ]
    r = random.Random(10)
    rows = []
    steady: dict[str, int] = {}
    peaks = PeakRss([p.pid for p in procs.values()])
    t_start = time.monotonic()
    with zenoh.open(zenoh_config()) as session:
        warm_up(session, keys)
        for service, kind, key, valid in plan:
            p = procs[service]
            payloads = [malformed(valid, i, r) for i in range(a.per_key)]
            before = rss_bytes(p.pid) if p.poll() is None else 0
            steady.setdefault(service, before)  # at work and at rest: before its first batch
            peaks.take(p.pid)
            if kind == "query":
                counts = fuzz_query(session, key, payloads)
            else:
                pub = session.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK)
                for payload in payloads:
                    pub.put(payload)
                pub.undeclare()
                counts = {}
            settle = time.monotonic() + SETTLE_S  # the service may still be working off the batch
            while p.poll() is None and rss_bytes(p.pid) > 1.2 * steady[service] and time.monotonic() < settle:
                time.sleep(0.25)
            crashed = p.poll() is not None
            after = rss_bytes(p.pid) if not crashed else 0
            peak = max(peaks.take(p.pid), before, after)
            rows.append(
                (
                    key.removeprefix(keys.prefix + "/"),
                    kind,
                    len(payloads),
                    counts,
                    crashed,
                    before,
                    peak,
                    after,
                )
            )
    time.sleep(2.0)
    end = {name: (rss_bytes(p.pid) if p.poll() is None else 0) for name, p in procs.items()}
    peaks.stop.set()
    for p in procs.values():
        p.terminate()
        p.wait(30)
    print(f"{a.per_key} malformed payloads per key to the running services (separate processes, one machine, "
          f"2 CPUs); {sum(row[2] for row in rows)} in {time.monotonic() - t_start:.0f} s\n")  # fmt: skip
    print("| key | kind | tried | ok | error-replied | no reply | crashed | RSS before / peak / after (MB) |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for key, kind, n, c, crashed, before, peak, after in rows:
        cells = [str(c[k]) for k in ("ok", "error-replied", "no reply")] if c else ["-", "-", "-"]
        print(f"| {key} | {kind} | {n} | {' | '.join(cells)} | {'yes' if crashed else 'no'} | "
              f"{before / 1e6:.0f} / {peak / 1e6:.0f} / {after / 1e6:.0f} |")  # fmt: skip
    print(
        "\n| service | RSS steady (MB) | peak (MB) | at the end (MB) | end / steady (reference: 1.20x at most) |"
    )
    print("|---|---:|---:|---:|---:|")
    for name in procs:
        peak = max(row[6] for row, svc in zip(rows, plan, strict=True) if svc[0] == name)
        print(f"| {name} | {steady[name] / 1e6:.0f} | {peak / 1e6:.0f} | {end[name] / 1e6:.0f} | "
              f"{end[name] / steady[name]:.2f}x |")  # fmt: skip
    no_reply = sum(row[3].get("no reply", 0) for row in rows)
    crashes = sum(row[4] for row in rows)
    print(f"\nno reply: {no_reply}, crashed: {crashes} (logs in {tmp})")
    return 1 if no_reply or crashes else 0


if __name__ == "__main__":
    sys.exit(main())
