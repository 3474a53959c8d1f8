"""A bare Zenoh put -> subscriber of one 640x480 xyz+rgb cloud's bytes (4.9 MB) between two local
processes, with and without Zenoh shared memory: the transport's floor that ``bench_system.py``
compares the pipeline with.

Modes (the subscriber's config matches the publisher's):

- ``off``: shared memory off (``$SOFIA_ZENOH_SHM=off``): the bytes go through the session's Unix
  socket;
- ``on``: SofIA's default (Zenoh's shared memory on, its ``transport_optimization``): the
  publisher's bytes are copied into Zenoh's SHM pool by the transport, the subscriber maps them;
- ``provider``: the publisher allocates a buffer from a ``zenoh.shm.ShmProvider``, writes the cloud
  into it and puts the buffer (zenoh-python's ``zenoh.shm`` API, marked unstable).

Latency: the subscriber's ``time.time_ns()`` after ``payload.to_bytes()`` (a Python service needs
the bytes) minus the stamp the publisher wrote into the payload just before ``put``.

    .venv/bin/python bench/bench_transport.py [--messages 300] [--rate 30]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

SIZE = 4_915_264  # bytes of a 640x480 xyz+rgb PointCloud2 CDR (bench_codec)
MODES = ("off", "on", "provider")


def session_config(mode: str) -> object:
    from sofia_runtime.zenoh_config import zenoh_config

    return zenoh_config(env=dict(os.environ, SOFIA_ZENOH_SHM="off" if mode == "off" else "on"))


def subscriber(key: str, mode: str, n: int, out: Path) -> None:
    """Own process: latency of each sample from the stamp in its first 8 bytes."""
    import zenoh

    latencies: list[float] = []
    shm = [0]

    def on_sample(sample: zenoh.Sample) -> None:
        shm[0] += sample.payload.as_shm() is not None
        data = sample.payload.to_bytes()
        latencies.append((time.time_ns() - int.from_bytes(data[:8], "little")) / 1e6)

    with zenoh.open(session_config(mode)) as session:
        session.declare_subscriber(key, on_sample)
        print("ready", flush=True)
        deadline = time.monotonic() + 120
        while len(latencies) < n and time.monotonic() < deadline:
            time.sleep(0.05)
    out.write_text(json.dumps({"latencies": latencies, "shm": shm[0]}))


def publish(key: str, mode: str, n: int, rate: float) -> None:
    import zenoh
    from sofia_runtime.client import matched

    data = bytearray(np.random.default_rng(0).integers(0, 256, SIZE, dtype=np.uint8).tobytes())
    with zenoh.open(session_config(mode)) as session:
        pub = session.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK)
        deadline = time.monotonic() + 10
        while not matched(pub) and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.5)
        provider = None
        if mode == "provider":
            from zenoh.shm import GarbageCollect, ShmProvider

            provider = ShmProvider.default_backend(4 * SIZE)  # 4 clouds, as the replayer's pool
        t0, failed = time.monotonic(), 0
        for i in range(n):
            due = t0 + i / rate
            time.sleep(max(0.0, due - time.monotonic()))
            if provider is not None:
                try:
                    buf = provider.alloc(SIZE, GarbageCollect())
                except zenoh.ZError:  # the pool is full: buffers still held by the subscriber
                    failed += 1
                    data[:8] = time.time_ns().to_bytes(8, "little")
                    pub.put(data)
                    continue
                buf[:] = data
                buf[:8] = time.time_ns().to_bytes(8, "little")
                pub.put(buf)
                del buf
            else:
                data[:8] = time.time_ns().to_bytes(8, "little")
                pub.put(data)
        time.sleep(0.5)
        if failed:
            print(f"provider: {failed} allocations failed (sent without the provider)", flush=True)


def measure(mode: str, n: int, rate: float) -> dict[str, float]:
    """Run a subscriber process and a publisher process; latency percentiles (ms) and CPU."""
    import tempfile
    import uuid

    key = f"bench/transport/{uuid.uuid4().hex[:8]}"
    with tempfile.TemporaryDirectory(prefix="sofia-transport-") as tmp:
        return _measure(key, Path(tmp) / "sub.json", mode, n, rate)


def _measure(key: str, out: Path, mode: str, n: int, rate: float) -> dict[str, float]:
    me = [sys.executable, __file__]
    sub = subprocess.Popen(
        [*me, "--role", "sub", key, mode, str(n), str(out)], stdout=subprocess.PIPE, text=True
    )
    assert sub.stdout is not None and sub.stdout.readline().strip() == "ready"
    t0 = os.times()
    pub = subprocess.run([*me, "--role", "pub", key, mode, str(n), str(rate)], check=True)
    sub.wait(60)
    t1 = os.times()
    del pub
    res = json.loads(out.read_text())
    lat = np.array(res["latencies"])
    cpu = (t1.children_user + t1.children_system - t0.children_user - t0.children_system) / (n / rate)
    return {
        "received": float(lat.size), "shm": float(res["shm"]), "p50": float(np.percentile(lat, 50)),
        "p99": float(np.percentile(lat, 99)), "max": float(lat.max()), "cpu": cpu * 100,
    }  # fmt: skip


def table(n: int, rate: float, modes: tuple[str, ...] = MODES) -> dict[str, dict[str, float]]:
    results = {m: measure(m, n, rate) for m in modes}
    base = results[modes[0]]
    print(
        f"bare Zenoh put -> subscriber (separate processes), {SIZE / 1e6:.2f} MB, {n} messages at {rate:.0f} Hz\n"
    )
    print(
        "| mode | received | via SHM | p50 ms | p99 ms | max ms | CPU pub+sub with start-up, % of a core | p50 ratio to shm off |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for m, r in results.items():
        print(
            f"| {m} | {r['received']:.0f}/{n} | {r['shm']:.0f} | {r['p50']:.2f} | {r['p99']:.2f} | {r['max']:.2f} "
            f"| {r['cpu']:.0f} | {r['p50'] / base['p50']:.2f}x |"
        )
    return results


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--messages", type=int, default=300, help="messages per mode (default 300)")
    ap.add_argument("--rate", type=float, default=30.0, help="put rate, Hz (default 30)")
    ap.add_argument("--role", nargs=5, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.role:
        role, key, mode, n, x = a.role
        if role == "sub":
            subscriber(key, mode, int(n), Path(x))
        else:
            publish(key, mode, int(n), float(x))
        return 0
    table(a.messages, a.rate)
    return 0


if __name__ == "__main__":
    sys.exit(main())
