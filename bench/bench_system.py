"""End to end: replay 640x480 base-frame clouds at 30 Hz -> detector -> a separate subscriber.

The replayer restamps every cloud with its publish time (``--restamp``), so the latency is what
the issue asks for: arrival of the detection at a separate subscriber - the cloud's stamp (one
machine, one clock). The reference is the frame period (33.3 ms at 30 Hz): a detector that keeps
up has p99 below it. Also printed: frames lost (clouds the subscriber saw without a detection),
the detector's own dropped count, CPU per process (from /proc), and the detector's memory after a
10 s warm-up and at the end (flat = no leak).

Baselines measured in the same run: a bare Zenoh put -> subscriber of the same 4.9 MB between two
processes (``bench_transport.py``: Zenoh shared memory on, as SofIA's sessions use it, and off),
to which the plumbing's share of the latency (latency minus the detector's own ``detect()`` time,
from each detection's ``timings_ms``) is compared; and the replayer's CPU at the same rate reading
the file lazily (decompressing every loop) against ``--preload``. The service's ``detect()`` time
is compared with the same clouds' ``detect()`` in this process, back to back and paced at the frame
period (``detect_pace.py``).

    .venv/bin/python bench/bench_system.py                 # 60 s (the issue's benchmark)
    .venv/bin/python bench/bench_system.py --rate 90       # three cameras' worth
    .venv/bin/python bench/bench_system.py --seconds 600   # the 10-minute soak
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from pathlib import Path
from typing import Any

import numpy as np
from sofia_runtime.memory import rss_bytes

REPO = Path(__file__).resolve().parents[1]
SOFIA = str(Path(sys.executable).with_name("sofia"))
CLK_TCK = os.sysconf("SC_CLK_TCK")


def cpu_model() -> str:
    """The processor's model name and clock as the kernel reports them (runs on hosts of several
    speeds are compared by it), or "processor unknown"."""
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return "processor unknown"
    info: dict[str, str] = {}
    for line in text.splitlines():  # the first processor's fields
        key, sep, value = line.partition(":")
        if sep:
            info.setdefault(key.strip(), value.strip())
    name, mhz = info.get("model name") or "processor unknown", info.get("cpu MHz")
    return f"{name} at {float(mhz):.0f} MHz" if mhz else name


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK


def subscriber(robot: str, seconds: float, out: Path) -> None:
    """Runs in its own process: record arrival times of clouds and detections."""
    import zenoh
    from sofia_runtime import zenoh_config
    from sofia_runtime.shm import SharedReader
    from sofia_schemas import Keys, pointcloud
    from sofia_schemas.messages import Detection

    keys = Keys(robot)
    clouds: set[int] = set()
    latencies: list[float] = []
    detect_ms: list[float] = []
    counts = {"clouds": 0, "detections": 0, "unmatched": 0, "objects": 0}
    lock = threading.Lock()

    reader = SharedReader()  # the stamp read in place: the subscriber copies no cloud

    def on_cloud(sample: zenoh.Sample) -> None:
        stamp = pointcloud.decode(reader.received(sample)[0]).stamp_ns
        with lock:
            clouds.add(stamp)
            counts["clouds"] += 1

    def on_detection(sample: zenoh.Sample) -> None:
        t_ns = time.time_ns()
        det = Detection.model_validate_json(sample.payload.to_bytes())
        with lock:
            counts["detections"] += 1
            counts["objects"] += len(det.objects)
            counts["unmatched"] += det.stamp_ns not in clouds
            latencies.append((t_ns - det.stamp_ns) / 1e9)
            detect_ms.append(float(det.timings_ms.get("total_ms", 0.0)))

    with zenoh.open(zenoh_config()) as session:
        session.declare_subscriber(keys.points, on_cloud)
        session.declare_subscriber(keys.detections, on_detection)
        print("subscriber ready", flush=True)
        time.sleep(seconds)
    with lock:
        out.write_text(json.dumps({"latencies": latencies, "detect_ms": detect_ms, **counts}))


def start(args: list[str], env: dict[str, str], log: Path) -> subprocess.Popen[bytes]:
    return subprocess.Popen(args, stdout=open(log, "wb"), stderr=subprocess.STDOUT, env=env, cwd=REPO)


def wait_log(path: Path, text: str, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if path.exists() and text in path.read_text(errors="replace"):
            return
        time.sleep(0.1)
    raise SystemExit(f"{text!r} not in {path}:\n{path.read_text(errors='replace')[-2000:]}")


def plumbing_rows(lat: np.ndarray, detect_ms: np.ndarray, baseline: dict[str, dict[str, float]]) -> None:
    """Rows: detect() time, the plumbing (latency minus detect()) and the bare put -> sub baseline."""
    if not lat.size:
        return
    plumbing = lat - detect_ms
    for q in (50, 99):
        d, p = float(np.percentile(detect_ms, q)), float(np.percentile(plumbing, q))
        print(
            f"| detect() p{q} (the detector's own timing) | {d:.1f} ms | latency p{q} | {d / np.percentile(lat, q):.2f}x |"
        )
        for mode, name in (
            ("on", "bare Zenoh put -> sub, SHM"),
            ("off", "bare Zenoh put -> sub, no SHM"),
        ):
            if mode in baseline:
                b = baseline[mode][f"p{q}"]
                print(
                    f"| plumbing p{q} (latency - detect()) | {p:.1f} ms | {name} p{q} {b:.2f} ms | {p / b:.2f}x |"
                )


def replay_cpu_runs(rec: Path, env: dict[str, str], tmp: Path, seconds: float) -> dict[str, float]:
    """CPU (% of one core) of ``sofia replay play --loop --restamp`` at the recorded rate, lazily and
    with --preload, with a subscriber process taking every cloud."""
    robot = env["SOFIA_ROBOT"]
    out: dict[str, float] = {}
    sub = start([sys.executable, __file__, "--subscriber", robot, str(2 * seconds + 20), str(tmp / "cpu.json")],
                env, tmp / "cpu-sub.log")  # fmt: skip
    wait_log(tmp / "cpu-sub.log", "subscriber ready")
    for name, extra in (("lazy", []), ("preload", ["--preload"])):
        play = start(
            [SOFIA, "replay", "play", str(rec), "--loop", "--restamp", *extra], env, tmp / f"cpu-{name}.log"
        )
        wait_log(tmp / f"cpu-{name}.log", "preloaded" if extra else "replaying")
        time.sleep(2.0)  # started, and (preload) the file read: the steady state
        c0, t0 = cpu_seconds(play.pid), time.monotonic()
        time.sleep(seconds)
        out[name] = (cpu_seconds(play.pid) - c0) / (time.monotonic() - t0) * 100
        play.send_signal(signal.SIGTERM)
        play.wait(20)
    sub.send_signal(signal.SIGTERM)
    sub.wait(20)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="seconds of replay (default 60)")
    ap.add_argument("--rate", type=float, default=30.0, help="cloud rate, Hz (default 30)")
    ap.add_argument(
        "--backlog", type=int, default=1, help="the detector's --backlog (default 1: only the latest cloud)"
    )
    ap.add_argument(
        "--no-preload", action="store_true", help="replay reading the file lazily (default: --preload)"
    )
    ap.add_argument(
        "--baseline-messages", type=int, default=300, metavar="N",
        help="messages of the bare Zenoh put -> subscriber baseline, per mode (default 300; 0: skip)",
    )  # fmt: skip
    ap.add_argument(
        "--replay-cpu-seconds", type=float, default=15.0, metavar="S",
        help="seconds of each replay-CPU run, lazy and preloaded (default 15; 0: skip)",
    )  # fmt: skip
    ap.add_argument("--subscriber", nargs=3, metavar=("ROBOT", "SECONDS", "OUT"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.subscriber:
        subscriber(a.subscriber[0], float(a.subscriber[1]), Path(a.subscriber[2]))
        return 0

    from bench_transport import measure
    from detect_pace import paced_detect_ms
    from sofia_replay.synth import write_scene_set

    robot = "bench" + uuid.uuid4().hex[:6]
    env = dict(os.environ, SOFIA_ROBOT=robot, PYTHONUNBUFFERED="1")
    tmp = Path(tempfile.mkdtemp(prefix="sofia-e2e-"))
    rec = tmp / "scenes.mcap"
    n_frames = int(a.rate)  # one second of clouds, played in a loop
    write_scene_set(rec, "mixed", n_frames, seed=11, rate_hz=a.rate, frames="base")
    baseline = {}
    if a.baseline_messages:  # first: nothing else of this benchmark runs yet
        baseline = {m: measure(m, a.baseline_messages, a.rate) for m in ("on", "off")}
    replay_cpu = replay_cpu_runs(rec, env, tmp, a.replay_cpu_seconds) if a.replay_cpu_seconds else {}
    pace = paced_detect_ms(rec, 1.0 / a.rate)  # in this process, before the services start

    det = start([SOFIA, "detector", "serve", "--backlog", str(a.backlog)], env, tmp / "detector.log")
    wait_log(tmp / "detector.log", "detector ready")
    out = tmp / "sub.json"
    sub_s = a.seconds + 15.0
    sub = start([sys.executable, __file__, "--subscriber", robot, str(sub_s), str(out)], env, tmp / "sub.log")
    wait_log(tmp / "sub.log", "subscriber ready")
    time.sleep(1.0)
    rss0 = rss_bytes(det.pid) / 1e6
    preload = [] if a.no_preload else ["--preload"]
    play = start(
        [SOFIA, "replay", "play", str(rec), "--loop", "--restamp", *preload], env, tmp / "replay.log"
    )
    wait_log(tmp / "replay.log", "preloaded" if preload else "replaying")  # started (and read)
    cpu0 = {
        "detector": cpu_seconds(det.pid),
        "subscriber": cpu_seconds(sub.pid),
        "replay": cpu_seconds(play.pid),
    }
    t0 = time.monotonic()
    rss_samples = [rss0]
    while time.monotonic() - t0 < a.seconds:
        time.sleep(min(5.0, a.seconds))
        rss_samples.append(rss_bytes(det.pid) / 1e6)
    cpu1 = {
        "replay": cpu_seconds(play.pid),
        "detector": cpu_seconds(det.pid),
        "subscriber": cpu_seconds(sub.pid),
    }
    elapsed = time.monotonic() - t0
    play.send_signal(signal.SIGTERM)
    play.wait(20)
    sub.wait(sub_s + 30)
    status = subprocess.run([SOFIA, "query", f"sofia/{robot}/detector/status", "--json"], env=env,
                            capture_output=True, text=True, timeout=30).stdout  # fmt: skip
    det.send_signal(signal.SIGTERM)
    det.wait(20)
    rec.unlink()  # hundreds of MB; the logs stay in the temporary folder
    res = json.loads(out.read_text())
    lat = np.array(res["latencies"]) * 1000
    period = 1000.0 / a.rate
    counters: dict[str, Any] = {}
    for line in status.splitlines():
        try:
            counters = json.loads(line)["json"]["counters"]
        except (ValueError, KeyError):
            continue
    dropped = str(counters.get("dropped", "?"))
    print(
        f"{a.seconds:.0f} s of 640x480 base-frame clouds replayed at {a.rate:.0f} Hz ({n_frames}-frame synthetic "
        f"recording in a loop, restamped{', preloaded' if preload else ''}) -> sofia detector serve --backlog "
        f"{a.backlog} -> a subscriber in a separate process; {os.cpu_count()} CPUs ({cpu_model()}), load average "
        f"{' '.join(f'{x:.1f}' for x in os.getloadavg())} at the end\n"
    )
    print("| metric | value | reference | ratio |")
    print("|---|---:|---:|---:|")
    for name, q in (("latency p50", 50), ("latency p99", 99)):
        v = float(np.percentile(lat, q)) if lat.size else float("nan")
        print(f"| {name} | {v:.1f} ms | frame period {period:.1f} ms | {v / period:.2f}x |")
    mx = float(lat.max()) if lat.size else float("nan")
    print(f"| latency max | {mx:.1f} ms | frame period {period:.1f} ms | {mx / period:.2f}x |")
    lost = res["clouds"] - res["detections"]
    print(
        f"| clouds received by the subscriber | {res['clouds']} | {a.rate * elapsed:.0f} expected | "
        f"{res['clouds'] / (a.rate * elapsed):.2f}x |"
    )
    print(
        f"| detections received | {res['detections']} | {res['clouds']} clouds | "
        f"{res['detections'] / max(res['clouds'], 1):.3f}x |"
    )
    plumbing_rows(lat, np.array(res["detect_ms"]), baseline)
    d50 = float(np.percentile(res["detect_ms"], 50)) if res["detect_ms"] else float("nan")
    for name, v in (("one process, paced at the frame period", pace["paced"]),
                    ("one process, back to back", pace["back_to_back"])):  # fmt: skip
        print(f"| detect() p50 in the service | {d50:.1f} ms | {name} {v:.2f} ms | {d50 / v:.2f}x |")
    print(f"| frames lost (clouds without detection) | {lost} | 0 | |")
    print(f"| detector's dropped (stale) clouds | {dropped} | 0 | |")
    read, received = counters.get("shm_read", 0), counters.get("received", 0)
    print(f"| clouds the detector read in place from shared memory | {read} | {received} received | "
          f"{read / max(received, 1):.2f}x |")  # fmt: skip
    for name in ("replay", "detector", "subscriber"):
        cpu = (cpu1[name] - cpu0[name]) / elapsed * 100
        print(f"| CPU {name} | {cpu:.0f} % of one core | 100 % | {cpu / 100:.2f}x |")
    if replay_cpu:
        lazy, pre = replay_cpu["lazy"], replay_cpu["preload"]
        print(f"| CPU replay alone, --preload ({a.replay_cpu_seconds:.0f} s) | {pre:.1f} % of one core "
              f"| lazy (zstd file) {lazy:.1f} % | {pre / lazy:.2f}x |")  # fmt: skip
    warm = rss_samples[min(2, len(rss_samples) - 1)]  # after 10 s of clouds
    quarters = [
        rss_samples[min(len(rss_samples) - 1, round(q * (len(rss_samples) - 1)))] for q in (0.25, 0.5, 0.75)
    ]
    print(
        f"| detector memory at 1/4, 1/2, 3/4 of the run | {quarters[0]:.0f}, {quarters[1]:.0f}, {quarters[2]:.0f} MB "
        f"| flat after warm-up | {quarters[2] / quarters[0]:.2f}x |"
    )
    print(
        f"| detector memory: idle, after 10 s, end (max) | {rss_samples[0]:.0f}, {warm:.0f}, "
        f"{rss_samples[-1]:.0f} ({max(rss_samples):.0f}) MB | flat after warm-up | {rss_samples[-1] / warm:.2f}x |"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
