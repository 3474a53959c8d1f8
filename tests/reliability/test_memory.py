"""After an overload, the detector's resident memory comes back to within 20 % of its steady value
(glibc arenas bounded, free pages handed back once a second). The overload: clouds and detect
queries with payloads of every size (valid clouds, cut clouds, random bytes) from 3 threads, and
valid clouds at 100 Hz."""

from __future__ import annotations

import os
import random
import threading
import time

import numpy as np
import zenoh
from sofia_runtime import zenoh_config
from sofia_runtime.memory import rss_bytes
from sofia_schemas import Keys, pointcloud

from .conftest import Service

OVERLOAD_S = 8.0
SETTLE_S = 15.0  # the most the memory may take to come back


def _cloud(rng: np.random.Generator) -> bytes:
    """A 640x480 cloud of a plane 0.8 m below the camera, in the base frame."""
    points = rng.normal([0.5, 0.0, 0.0], [0.3, 0.3, 0.002], size=(480, 640, 3))
    return bytes(pointcloud.encode_points(points, stamp_ns=time.time_ns(), frame_id="panda_link0"))


def test_detector_memory_returns_after_overload(detector: Service, module_robot: str) -> None:
    keys = Keys(module_robot)
    rng = np.random.default_rng(0)
    clouds = [_cloud(rng) for _ in range(3)]
    with zenoh.open(zenoh_config()) as session:
        pub = session.declare_publisher(keys.points)
        for i in range(15):  # steady: the detector at work at its usual rate
            pub.put(clouds[i % 3])
            time.sleep(0.1)
        time.sleep(3.0)
        steady = rss_bytes(detector.pid)
        stop, peak = threading.Event(), [steady]

        def flood(seed: int) -> None:
            r = random.Random(seed)
            while not stop.is_set():
                c = clouds[r.randrange(3)]
                size = r.randint(1, len(c) + 3_000_000)
                payload = (c * 2)[:size] if r.random() < 0.5 else os.urandom(size)
                pub.put(payload)
                session.get(
                    keys.detect, lambda _reply: None, payload=payload[: r.randint(1, 3_900_000)], timeout=30
                )

        def stream() -> None:  # valid clouds at 100 Hz keep the worker busy meanwhile
            i = 0
            while not stop.is_set():
                pub.put(clouds[i % 3])
                i += 1
                time.sleep(0.01)

        threads = [threading.Thread(target=flood, args=(s,)) for s in range(3)]
        threads.append(threading.Thread(target=stream))
        for t in threads:
            t.start()
        t0 = time.monotonic()
        while time.monotonic() - t0 < OVERLOAD_S:
            peak[0] = max(peak[0], rss_bytes(detector.pid))
            time.sleep(0.1)
        stop.set()
        for t in threads:
            t.join()
        deadline = time.monotonic() + SETTLE_S
        while (after := rss_bytes(detector.pid)) > 1.2 * steady and time.monotonic() < deadline:
            time.sleep(0.5)
    mb = 1e-6
    print(f"detector RSS: steady {steady * mb:.0f} MB, peak {peak[0] * mb:.0f} MB, after {after * mb:.0f} MB")
    assert peak[0] > steady, "the overload did not load the detector"
    assert after <= 1.2 * steady, (
        f"steady {steady * mb:.0f} MB, peak {peak[0] * mb:.0f}, after {after * mb:.0f}"
    )
    assert detector.popen.poll() is None
