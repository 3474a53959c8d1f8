"""Replay throughput of 640x480 xyz+rgb clouds over Zenoh on loopback, subscriber in another process.

Run: .venv/bin/python bench/bench_replay.py [--clouds 90]

Rows: ``sofia replay play`` (its own process) reading an MCAP file (zstd, as ``McapWriter``
writes by default, and uncompressed), as fast as possible and at the recorded 30 Hz; a
subscriber process counts the clouds it receives and checks each one's size and CRC-32.
Baseline, measured in the same run: a bare Zenoh publisher putting the same clouds from memory in
a loop (no file, no decoding) — the transport's ceiling on this machine.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import zlib
from pathlib import Path

import numpy as np

SOFIA = str(Path(sys.executable).with_name("sofia"))
H, W, HZ = 480, 640, 30.0


def make_clouds(n: int) -> list[bytes]:
    """``n`` distinct D435-like clouds (a noisy plane at 0.6 m, 3 % NaN, colours), CDR bytes."""
    from sofia_schemas import pointcloud

    rng = np.random.default_rng(0)
    v, u = np.mgrid[0:H, 0:W]
    rgb = rng.integers(0, 256, (H, W, 3), dtype=np.uint8)
    out = []
    for i in range(n):
        z = 0.6 + 0.0005 * rng.standard_normal((H, W))
        p = np.stack([(u - W / 2) / 615 * z, (v - H / 2) / 615 * z, z], axis=-1).astype(np.float32)
        p[rng.random((H, W)) < 0.03] = np.nan
        stamp_ns = 1_700_000_000_000_000_000 + int(i * 1e9 / HZ)
        out.append(bytes(pointcloud.encode_points(p, stamp_ns=stamp_ns, frame_id="panda_link0", rgb=rgb)))
    return out


def write_mcap(path: Path, clouds: list[bytes], compression: str) -> None:
    from sofia_replay.mcap_io import McapWriter
    from sofia_schemas.keys import TOPIC_POINTS

    with McapWriter(path, compression=compression) as w:
        for i, cdr in enumerate(clouds):
            w.write_cloud(TOPIC_POINTS, cdr, 1_700_000_000_000_000_000 + int(i * 1e9 / HZ))


# --- the subscriber process -------------------------------------------------------------------------
def subscribe(key: str, n: int, idle_s: float) -> None:
    """Count samples on ``key`` until ``n`` arrived or none for ``idle_s``; print a JSON line."""
    import threading

    from sofia_runtime.zenoh_config import open_session

    arrivals: list[tuple[float, int, int]] = []
    done = threading.Event()

    def on_sample(sample: object) -> None:
        payload = sample.payload.to_bytes()  # type: ignore[attr-defined]
        arrivals.append((time.monotonic(), len(payload), zlib.crc32(payload)))
        if len(arrivals) >= n:
            done.set()

    with open_session() as session:
        sub = session.declare_subscriber(key, on_sample)
        print("ready", flush=True)
        last_count, last_change = 0, time.monotonic()
        while not done.wait(0.1):
            if len(arrivals) != last_count:
                last_count, last_change = len(arrivals), time.monotonic()
            elif time.monotonic() - last_change > idle_s:
                break
        sub.undeclare()
    print(json.dumps({"arrivals": arrivals}), flush=True)


def start_subscriber(key: str, n: int) -> subprocess.Popen[str]:
    proc = subprocess.Popen(
        [sys.executable, __file__, "--subscribe", key, str(n)], stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()
    if line.strip() != "ready":
        raise RuntimeError(f"subscriber failed to start: {line!r}")
    return proc


def collect(proc: subprocess.Popen[str]) -> list[tuple[float, int, int]]:
    out, _ = proc.communicate(timeout=300)
    return [tuple(a) for a in json.loads(out.strip().splitlines()[-1])["arrivals"]]  # type: ignore[misc]


# --- publishers -------------------------------------------------------------------------------------
def raw_zenoh_put(key: str, clouds: list[bytes]) -> None:
    """Baseline: one Zenoh publisher, clouds from memory, as fast as possible (reliable, BLOCK)."""
    import zenoh
    from sofia_runtime.client import matched
    from sofia_runtime.zenoh_config import open_session
    from sofia_schemas.keys import ENCODING_CDR_POINTCLOUD2

    with open_session() as session:
        pub = session.declare_publisher(
            key, encoding=ENCODING_CDR_POINTCLOUD2, congestion_control=zenoh.CongestionControl.BLOCK
        )
        deadline = time.monotonic() + 20
        while not matched(pub) and time.monotonic() < deadline:
            time.sleep(0.05)
        for cdr in clouds:
            pub.put(cdr)
        time.sleep(0.3)


def run_case(name: str, robot: str, clouds: list[bytes], publish: list[str] | None) -> dict[str, object]:
    key = f"sofia/{robot}/points"
    sub = start_subscriber(key, len(clouds))
    t0 = time.monotonic()
    if publish is None:
        raw_zenoh_put(key, clouds)
    else:
        env = dict(os.environ, SOFIA_ROBOT=robot)
        subprocess.run(
            [SOFIA, "--log-level", "WARNING", *publish, "--wait-subscribers", "20"], env=env, check=True
        )
    wall = time.monotonic() - t0
    arrivals = collect(sub)
    expected = {(len(c), zlib.crc32(c)) for c in clouds}
    intact = sum((size, crc) in expected for _, size, crc in arrivals)
    span = arrivals[-1][0] - arrivals[0][0] if len(arrivals) > 1 else float("nan")
    rate = (len(arrivals) - 1) / span if len(arrivals) > 1 else 0.0
    return {
        "name": name, "sent": len(clouds), "received": len(arrivals), "intact": intact,
        "lost": len(clouds) - len(arrivals), "rate": rate, "mb_s": rate * len(clouds[0]) / 1e6, "wall": wall,
    }  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--clouds", type=int, default=90, help="clouds per run (3 s at 30 Hz)")
    parser.add_argument("--subscribe", nargs=2, metavar=("KEY", "N"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.subscribe:
        subscribe(args.subscribe[0], int(args.subscribe[1]), idle_s=5.0)
        return

    clouds = make_clouds(args.clouds)
    robot = f"bench{os.getpid()}"
    with tempfile.TemporaryDirectory() as tmp:
        zstd, plain = Path(tmp) / "zstd.mcap", Path(tmp) / "none.mcap"
        write_mcap(zstd, clouds, "zstd")
        write_mcap(plain, clouds, "none")
        play = ["replay", "play"]
        results = [
            run_case("bare Zenoh put from memory (baseline)", robot + "a", clouds, None),
            run_case("sofia replay play --fast (zstd MCAP)", robot + "b", clouds, [*play, str(zstd), "--fast"]),
            run_case("sofia replay play --fast (uncompressed)", robot + "c", clouds, [*play, str(plain), "--fast"]),
            run_case("sofia replay play at the recorded 30 Hz (zstd)", robot + "d", clouds, [*play, str(zstd)]),
        ]  # fmt: skip
    base = float(results[0]["rate"])  # type: ignore[arg-type]
    mb = len(clouds[0]) / 1e6
    print(f"{args.clouds} clouds of 640x480 xyz+rgb ({mb:.2f} MB each), Zenoh peer-to-peer on loopback, "
          f"subscriber in a separate process; {os.cpu_count()} CPUs\n")  # fmt: skip
    print("| mode | sent | received intact | lost | clouds/s delivered | MB/s | ratio |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for r in results:
        rate = float(r["rate"])  # type: ignore[arg-type]
        paced = "30 Hz" in str(r["name"])
        ratio = f"{rate / HZ:.2f}x of 30 Hz" if paced else f"{rate / base:.2f}x bare put"
        print(
            f"| {r['name']} | {r['sent']} | {r['intact']} | {r['lost']} | {rate:.1f} | "
            f"{float(r['mb_s']):.0f} | {ratio} |"  # type: ignore[arg-type]
        )


if __name__ == "__main__":
    main()
