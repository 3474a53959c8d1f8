"""Messages read in place from Zenoh shared memory (:mod:`sofia_runtime.shm`): the location a
publisher appends to the attachment, a subscriber in this process reading the bytes a publisher
process wrote without copying them, holding them while it reads, and copying (with the reason)
whenever a check fails."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
import tracemalloc
from typing import Any

import numpy as np
import pytest
import zenoh
from sofia_camera.meta import CloudMeta
from sofia_runtime import zenoh_config
from sofia_runtime.shm import MARK, Location, SharedReader, split_location, with_location
from sofia_schemas.messages.calibration import correction_applied

SIZE = 4_915_200 + 12  # a 640x480 cloud's data and some header
MESSAGES = 10

PUBLISHER = """
import sys, time, numpy as np, zenoh
from sofia_replay.preload import ShmBuffers
from sofia_runtime import zenoh_config
from sofia_runtime.client import matched
key, size, n = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
with zenoh.open(zenoh_config()) as session:
    pub = session.declare_publisher(key)
    while not matched(pub):
        time.sleep(0.05)
    out = ShmBuffers(True)
    for k in range(n):
        payload, attachment = out.payload(np.random.default_rng(k).bytes(size))
        pub.put(payload, attachment=attachment)
        time.sleep(0.1)
    print(out.fallbacks, out.unlocated, flush=True)
    sys.stdin.readline()
"""


def _message(k: int) -> bytes:
    return np.random.default_rng(k).bytes(SIZE)


def test_a_location_travels_at_the_end_of_any_attachment() -> None:
    loc = Location("0123456789.zenoh", 4096, SIZE, b"h" * MARK, b"t" * MARK)
    meta = CloudMeta(stamp_ns=5, color_stamp_ns=None, skew_ms=0.0, synced=True, frame_number=1,
                     device_time_ms=2.0, depth_corrected=True)  # fmt: skip
    for attachment in (None, b"", meta.attachment(), b"\nsofia.shm=not one"):
        rest, got = split_location(with_location(attachment, loc))
        assert got == loc and rest == (attachment or None)
    assert split_location(meta.attachment()) == (meta.attachment(), None)
    assert split_location(None) == (None, None)
    joined = with_location(meta.attachment(), loc)
    assert correction_applied(joined) and CloudMeta.from_attachment(joined) == meta
    assert with_location(b"x", None) == b"x"


@pytest.mark.parametrize(
    "text",
    [b"../etc/passwd.zenoh 0 64 " + b"00" * MARK + b" " + b"00" * MARK,  # a path, not a segment name
     b"seg.txt 0 64 " + b"00" * MARK + b" " + b"00" * MARK,  # not a Zenoh segment
     b"s.zenoh -1 64 " + b"00" * MARK + b" " + b"00" * MARK,  # negative offset
     b"s.zenoh 0 8 " + b"00" * MARK + b" " + b"00" * MARK,  # shorter than its marks
     b"s.zenoh 0 64 00 00",  # marks of the wrong length
     b"s.zenoh 0 64",  # fields missing
     b"\xff\xfe"],  # not text
)  # fmt: skip
def test_a_malformed_location_is_no_location(text: bytes) -> None:
    assert Location.parse(text) is None
    assert split_location(b"meta" + b"\nsofia.shm=" + text) == (b"meta", None)


def test_a_subscriber_reads_messages_in_place_and_holds_them_while_it_reads(robot_id: str) -> None:
    """A publisher process writes 10 messages of 4.9 MB into its pool (room for 3-4). This process
    keeps a view of each: the views are the messages, read-only, reading one allocates nothing like
    its size (a copy does), and while they are held the publisher gets no buffer (it puts the rest
    as plain bytes, without a location) and the held bytes stay the same, also after the publisher
    has gone. A location moved by 64 bytes, past the segment's end, or on a payload that is not in
    shared memory here, is refused with its reason."""
    key = f"test/shm/{robot_id}"
    reader = SharedReader()
    views: list[memoryview | None] = []
    view_peak: list[int] = []
    copy_peak: list[int] = []
    refused: list[tuple[Any, str]] = []

    def on(sample: zenoh.Sample) -> None:
        att = sample.attachment.to_bytes() if sample.attachment is not None else None
        tracemalloc.start()
        try:
            view = reader.view(sample.payload, att)
            view_peak.append(tracemalloc.get_traced_memory()[1])
            tracemalloc.reset_peak()
            sample.payload.to_bytes()
            copy_peak.append(tracemalloc.get_traced_memory()[1])
        finally:
            tracemalloc.stop()
        views.append(view)
        _, loc = split_location(att)
        if loc is not None and not refused:
            moved = Location(loc.segment, loc.offset + 64, loc.size, loc.head, loc.tail)
            refused.append((reader.view(sample.payload, with_location(None, moved)), reader.reason))
            small = zenoh.ZBytes(b"x" * 100)
            refused.append((reader.view(small, att), reader.reason))
            past = Location(loc.segment, loc.offset, 1 << 40, loc.head, loc.tail)
            refused.append((reader.view(sample.payload, with_location(None, past)), reader.reason))

    proc = subprocess.Popen([sys.executable, "-c", PUBLISHER, key, str(SIZE), str(MESSAGES)],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)  # fmt: skip
    watchdog = threading.Timer(90, proc.kill)
    watchdog.start()
    try:
        with zenoh.open(zenoh_config()) as session:
            sub = session.declare_subscriber(key, on)
            assert proc.stdout is not None and proc.stdin is not None
            fallbacks, unlocated = (int(x) for x in proc.stdout.readline().split())
            deadline = time.monotonic() + 10
            while len(views) < MESSAGES and time.monotonic() < deadline:
                time.sleep(0.02)
            held = [v for v in views if v is not None]
            assert len(views) == MESSAGES and len(held) >= 2, [v is not None for v in views]
            assert views[len(held) :] == [None] * (MESSAGES - len(held)), "the pool's buffers are held"
            assert fallbacks == MESSAGES - len(held) and unlocated == 0
            assert all(v.readonly and v.tobytes() == _message(k) for k, v in enumerate(held))
            assert max(view_peak) < 64_000 <= SIZE <= min(copy_peak), (
                view_peak,
                copy_peak,
            )  # a copy is traced
            assert reader.read == len(held)
            assert refused[0][0] is None and "are not the message's" in refused[0][1]
            assert refused[1][0] is None and "not in shared memory" in refused[1][1]
            assert refused[2][0] is None and "run past the" in refused[2][1]
            assert reader.copied == 3
            sub.undeclare()
    finally:
        if proc.stdin is not None:
            proc.stdin.close()  # the publisher leaves
        proc.wait(30)
        watchdog.cancel()
    assert all(v.tobytes() == _message(k) for k, v in enumerate(held)), "held views never change"


def test_a_reader_turned_off_copies_everything() -> None:
    loc = Location("0123456789.zenoh", 0, SIZE, b"h" * MARK, b"t" * MARK)
    reader = SharedReader(enabled=False)
    assert reader.view(zenoh.ZBytes(b"x" * 100), with_location(None, loc)) is None and reader.read == 0
