"""Arm benchmark: flange-pose publish rate and latency (robot state -> bus) against the robot's
state rate.

franky-sim runs as its own process, ``sofia arm serve --robot-ip <its address>`` as another, and
this process subscribes to ``flange/pose`` and ``arm/state``: first with the arm at rest, then
while it moves back and forth. For each pose: latency = time received here - its stamp (the
robot's time mapped onto the bus clock). Baselines in the same run: the robot's own state rate
(its clock's ticks per second, 1 kHz on a real robot; franky-sim on a busy machine is slower)
and the configured publish rate.

Run: ``.venv/bin/python bench/bench_arm.py [--seconds 10] [--rate 200]`` (about a minute).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

import numpy as np
import zenoh
from sofia_arm.sim import start_sim
from sofia_runtime.client import ask
from sofia_runtime.zenoh_config import zenoh_config
from sofia_schemas.keys import ENCODING_JSON, Keys
from sofia_schemas.messages import ArmState, ServiceStatus
from sofia_schemas.rosmsg import decode_flange_pose

SOFIA = str(Path(sys.executable).with_name("sofia"))
Q_A = [0.3, -0.3, 0.2, -2.0, 0.1, 1.8, 0.3]
Q_B = [-0.3, 0.2, -0.2, -1.7, -0.1, 2.0, 1.0]


def measure(session: zenoh.Session, keys: Keys, seconds: float) -> dict[str, float]:
    received: list[tuple[int, int]] = []  # (received_ns, stamp_ns)
    states: list[ArmState] = []
    lock = threading.Lock()

    def on_pose(sample: zenoh.Sample) -> None:
        now = time.time_ns()
        stamp = decode_flange_pose(sample.payload.to_bytes()).stamp_ns
        with lock:
            received.append((now, stamp))

    def on_state(sample: zenoh.Sample) -> None:
        states.append(ArmState.model_validate_json(sample.payload.to_bytes()))

    subs = [
        session.declare_subscriber(keys.flange_pose, on_pose),
        session.declare_subscriber(keys.arm_state, on_state),
    ]
    time.sleep(seconds)
    for s in subs:
        s.undeclare()
    r = np.array(received, dtype=np.int64)
    if len(r) < 2:
        raise SystemExit(f"only {len(r)} flange poses arrived in {seconds:g} s")
    lat_ms = (r[:, 0] - r[:, 1]) * 1e-6
    span = (r[-1, 0] - r[0, 0]) * 1e-9
    robot_hz = float(np.median([s.robot_rate_hz for s in states])) if states else float("nan")
    return {
        "n": len(r), "rate": (len(r) - 1) / span, "robot_hz": robot_hz,
        "p50": float(np.percentile(lat_ms, 50)), "p99": float(np.percentile(lat_ms, 99)), "max": float(lat_ms.max()),
        "monotonic": float(np.all(np.diff(r[:, 1]) > 0)),
    }  # fmt: skip


def mover(session: zenoh.Session, keys: Keys, stop: threading.Event) -> None:
    targets = [Q_A, Q_B]
    i = 0
    while not stop.is_set():
        payload = json.dumps({"command": "move_joints", "q": targets[i % 2], "speed": 0.5, "timeout_s": 120})
        list(session.get(keys.arm_command, payload=payload, encoding=ENCODING_JSON, timeout=130))
        i += 1


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--rate", type=float, default=200.0, help="the service's --rate")
    ap.add_argument(
        "--robot-ip", help="a real robot instead of franky-sim (it moves: keep the workspace clear)"
    )
    args = ap.parse_args()
    robot_id = "bench" + uuid.uuid4().hex[:6]
    sim = None if args.robot_ip else start_sim()
    host = args.robot_ip or sim.host  # type: ignore[union-attr]
    env = dict(os.environ, SOFIA_ROBOT=robot_id, PYTHONUNBUFFERED="1")
    service = subprocess.Popen([SOFIA, "--log-level", "WARNING", "arm", "serve", "--robot-ip", host,
                                "--max-speed", "0.5", "--hz", str(args.rate)], env=env)  # fmt: skip
    keys = Keys(robot_id)
    try:
        with zenoh.open(zenoh_config()) as session:
            ask(session, keys.status("arm"), ServiceStatus, timeout=120.0)  # the service is up
            time.sleep(2.0)  # connected, publishing, discovered
            rest = measure(session, keys, args.seconds)
            stop = threading.Event()
            t = threading.Thread(target=mover, args=(session, keys, stop), daemon=True)
            t.start()
            time.sleep(1.0)
            moving = measure(session, keys, args.seconds)
            stop.set()
    finally:
        service.terminate()
        service.wait(15)
        if sim is not None:
            sim.stop()
    cpus = os.cpu_count()
    robot = f"the robot at {host}" if sim is None else f"franky-sim ({host})"
    print(f"{robot} -> sofia arm serve --rate {args.rate:g} -> a subscriber in a separate process; "
          f"{args.seconds:g} s at rest, then {args.seconds:g} s moving; {cpus} CPUs\n")  # fmt: skip
    print("| metric | at rest | moving | reference | ratio (moving) |")
    print("|---|---:|---:|---:|---:|")
    ref_rate = min(args.rate, moving["robot_hz"])
    print(
        f"| robot state rate (its clock) | {rest['robot_hz']:.0f} Hz | {moving['robot_hz']:.0f} Hz | 1000 Hz (real robot) | {moving['robot_hz'] / 1000:.2f}x |"
    )
    print(
        f"| flange poses received | {rest['rate']:.0f} Hz | {moving['rate']:.0f} Hz | min(--rate, robot) {ref_rate:.0f} Hz | {moving['rate'] / ref_rate:.2f}x |"
    )
    print(
        f"| poses >= 100 Hz | {'yes' if rest['rate'] >= 100 else 'NO'} | {'yes' if moving['rate'] >= 100 else 'NO'} | 100 Hz | {moving['rate'] / 100:.2f}x |"
    )
    period_ms = 1000.0 / max(moving["robot_hz"], 1e-3)
    for k in ("p50", "p99", "max"):
        print(f"| latency {k} (stamp -> bus) | {rest[k]:.2f} ms | {moving[k]:.2f} ms | robot state period {period_ms:.2f} ms | {moving[k] / period_ms:.2f}x |")  # fmt: skip
    print(f"| stamps strictly increasing | {bool(rest['monotonic'])} | {bool(moving['monotonic'])} | | |")
    print(f"| poses received | {rest['n']:.0f} | {moving['n']:.0f} | | |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
