"""Clouds written straight into Zenoh shared memory: the same bytes as the plain message, mapped by a
subscriber in another process, put as plain bytes (counted) when the pool is exhausted or SHM is off.

(A local subscriber's payload is SHM-backed after a plain put of more than 3 KB too: Zenoh's transport
copies it into its own pool, the copy this saves; what shows that the camera wrote into shared memory
is the payload it put, a ``ZShmMut``, and the ``direct`` count.)"""

from __future__ import annotations

import hashlib
import json
import os
import re
import subprocess
import sys
import threading
import time

import numpy as np
import zenoh
from sofia_camera import shm
from sofia_camera.cloud import CloudEncoder
from sofia_camera.intrinsics import Intrinsics
from sofia_camera.shm import CloudBuffers
from sofia_replay.preload import shm_enabled
from sofia_runtime import shm as runtime_shm
from sofia_runtime import zenoh_config
from sofia_runtime.client import matched

from .conftest import flange_above

SUBSCRIBER = """
import hashlib, json, sys, zenoh
from sofia_runtime import zenoh_config
from sofia_runtime.shm import SharedReader
reader = SharedReader()
with zenoh.open(zenoh_config()) as session:
    def on(sample):
        data = sample.payload.to_bytes()
        view = reader.view(sample.payload, sample.attachment.to_bytes() if sample.attachment else None)
        print(json.dumps({"sha": hashlib.sha256(data).hexdigest(), "shm": sample.payload.as_shm() is not None,
                          "in_place": None if view is None else hashlib.sha256(view).hexdigest()}), flush=True)
    sub = session.declare_subscriber(sys.argv[1], on)
    print("ready", flush=True)
    sys.stdin.readline()
"""


def _frame(seed: int = 1) -> tuple[np.ndarray, np.ndarray, Intrinsics]:
    rng = np.random.default_rng(seed)
    z_m = rng.uniform(0.3, 0.6, (48, 64)).astype(np.float32)
    z_m[::5, ::3] = np.nan
    z_m[1, 1], z_m[2, 2] = 0.0, np.inf
    return z_m, rng.integers(0, 256, (48, 64, 4), dtype=np.uint8), Intrinsics(64, 48, 60.0, 61.0, 31.5, 23.5)


def test_the_message_written_into_shared_memory_is_the_plain_message() -> None:
    z_m, bgra, intr = _frame()
    encoder = CloudEncoder()
    plain = encoder.encode(z_m, bgra, intr, 1_700_000_000_123_456_789)
    assert isinstance(plain, bytearray)
    buffers = CloudBuffers(enabled=True)
    held = [encoder.encode(z_m, bgra, intr, 1_700_000_000_123_456_789, buffers=buffers) for _ in range(8)]
    assert all(bytes(p) == plain for p in held)
    shm = [p for p in held if not isinstance(p, bytearray)]
    assert len(shm) >= 2 and buffers.direct == len(shm) and buffers.copied == 0, (len(shm), buffers.direct)
    assert buffers.fallbacks == len(held) - len(shm) > 0, "every buffer held: the pool is exhausted"
    del held, shm
    again = encoder.encode(z_m, bgra, intr, 1_700_000_000_123_456_789, buffers=buffers)
    assert not isinstance(again, bytearray) and bytes(again) == plain, "freed buffers are reused"
    off = CloudBuffers(enabled=shm_enabled({"SOFIA_ZENOH_SHM": "off"}))
    out = encoder.encode(z_m, bgra, intr, 1_700_000_000_123_456_789, buffers=off)
    assert isinstance(out, bytearray) and out == plain and off.direct == 0 and off.fallbacks == 0


def test_a_subscriber_process_maps_the_cloud_bit_identical(board_world, make_rig) -> None:  # type: ignore[no-untyped-def]
    rig = make_rig(board_world, 640, 480)
    T = flange_above(board_world)
    key = f"test/camera/shm/{os.getpid()}"
    proc = subprocess.Popen([sys.executable, "-c", SUBSCRIBER, key], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            text=True)  # fmt: skip
    watchdog = threading.Timer(90, proc.kill)  # a subscriber that never answers ends the test
    watchdog.start()
    try:
        assert proc.stdout is not None and proc.stdin is not None
        assert proc.stdout.readline().strip() == "ready"
        buffers = CloudBuffers(enabled=True)
        expected: list[str] = []
        with zenoh.open(zenoh_config()) as session:
            pub = session.declare_publisher(key)
            deadline = time.monotonic() + 60
            while not matched(pub) and time.monotonic() < deadline:
                time.sleep(0.1)
            for k in range(3):
                depth, rgb = rig.renderer.render(T)
                rig.camera.inject(depth, rgb, 1000.0 + 33.3 * k)
                pair = rig.camera.wait_pair(5.0)
                assert pair is not None and pair.color is not None
                stamp_ns = time.time_ns()
                rig.pipeline.buffers = None
                plain = rig.pipeline.build(pair, rig.camera, stamp_ns, None).cloud
                rig.pipeline.buffers = buffers
                out = rig.pipeline.build(pair, rig.camera, stamp_ns, None)
                assert not isinstance(out.cloud, bytearray), "written into shared memory"
                expected.append(hashlib.sha256(plain).hexdigest())
                pub.put(out.cloud, attachment=out.attachment)
            received = [json.loads(proc.stdout.readline()) for _ in expected]
            pub.undeclare()
    finally:
        watchdog.cancel()
        proc.kill()
        proc.wait(10)
    assert [r["sha"] for r in received] == expected, "the subscriber gets the plain message's bytes"
    assert all(r["shm"] for r in received), "the subscriber's payload is the shared-memory buffer"
    assert [r["in_place"] for r in received] == expected, (
        "and it reads the cloud there, where the camera said"
    )
    assert (
        buffers.direct == 3 and buffers.copied == 0 and buffers.fallbacks == 0 and buffers.pool.unlocated == 0
    )


def test_without_room_in_dev_shm_clouds_are_put_as_bytes_and_counted(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setattr(shm, "_shm_free", lambda: 40 << 20)  # a container's /dev/shm, partly used
    z_m, bgra, intr = _frame()
    big = Intrinsics(1280, 720, 900.0, 900.0, 639.5, 359.5)
    z_big = np.resize(z_m, (720, 1280))
    bgra_big = np.resize(bgra, (720, 1280, 4))
    buffers = CloudBuffers(enabled=True)
    small = CloudEncoder().encode(z_m, bgra, intr, 5, buffers=buffers)
    assert not isinstance(small, bytearray) and buffers.enabled, "a 64x48 pool fits"
    encoder = CloudEncoder()
    out = [encoder.encode(z_big, bgra_big, big, 5, buffers=buffers) for _ in range(2)]
    assert all(isinstance(o, bytearray) for o in out) and out[0] == encoder.encode(z_big, bgra_big, big, 5)
    assert (
        not buffers.enabled
        and buffers.fallbacks == 2
        and "/dev/shm has 42 MB free" in buffers.detail
        and "+16 MB" in buffers.detail
    )


def test_a_buffer_whose_address_cannot_be_checked_gets_the_message_copied_in(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    # a Zenoh whose buffers' repr gives no address
    monkeypatch.setattr(runtime_shm, "ADDRESS", re.compile(r"no such field (0x[0-9a-f]+)"))
    z_m, bgra, intr = _frame(2)
    encoder = CloudEncoder()
    plain = encoder.encode(z_m, bgra, intr, 7)
    buffers = CloudBuffers(enabled=True)
    out = [encoder.encode(z_m, bgra, intr, 7, buffers=buffers) for _ in range(2)]
    assert all(not isinstance(o, bytearray) and bytes(o) == plain for o in out)
    assert buffers.copied == 2 and buffers.direct == 0 and "does not report" in buffers.detail
