"""What the replayer puts: messages preloaded into memory (``--preload``), restamped in place, and
large ones written into Zenoh shared memory (:class:`ShmBuffers`, unless ``$SOFIA_ZENOH_SHM=off``).

Playing from memory costs no file reading or decompression per loop; restamping a preloaded
message writes its 8 stamp bytes in place (Zenoh copies what is put, so each put carries the
stamp written just before it) instead of copying the message.
"""

from __future__ import annotations

import logging
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import zenoh
from sofia_runtime.shm import MARK, Locator, with_location
from sofia_runtime.zenoh_config import shm_wanted

from .mcap_io import RecordedMessage, iter_messages
from .stamps import HEADER_FIRST, restamp

log = logging.getLogger(__name__)
HEADER_BYTES = 12  # CDR encapsulation (4) + header stamp (int32 sec, uint32 nanosec)


def preload(
    path: Path, topics: list[str] | None, start_ns: int, end_ns: int, restamped: bool
) -> list[RecordedMessage]:
    """The messages of ``path`` with ``start_ns <= log_time < end_ns`` on ``topics`` (None: all), in
    memory. With ``restamped``, messages that start with a header get a ``bytearray`` as data (to be
    restamped in place) and are checked now: one that cannot be restamped raises RecordingError."""
    t0 = time.monotonic()
    out = []
    for m in iter_messages(path, topics, start_ns, end_ns):
        if restamped and m.schema_name in HEADER_FIRST:
            restamp(m.data[:HEADER_BYTES], 0)  # refused now rather than while playing
            m = replace(m, data=bytearray(m.data))  # type: ignore[arg-type]  # restamped in place
        out.append(m)
    log.info(
        "preloaded %d messages, %.1f MB, in %.2f s", len(out), sum(len(m.data) for m in out) / 1e6,
        time.monotonic() - t0,
    )  # fmt: skip
    return out


def restamp_in_place(data: bytes | bytearray, stamp_ns: int) -> bytes | bytearray:
    """``data`` with its header stamp set to ``stamp_ns``: a preloaded ``bytearray`` is changed in
    place (no copy), ``bytes`` are copied once (:func:`~sofia_replay.stamps.restamp`)."""
    if isinstance(data, bytearray):
        data[:HEADER_BYTES] = restamp(bytes(data[:HEADER_BYTES]), stamp_ns)
        return data
    return restamp(data, stamp_ns)


class ShmBuffers:
    """Large messages written straight into a Zenoh shared-memory buffer before ``put``: one copy
    (the message into the buffer) where a ``put`` of the bytes costs two (into Zenoh, then into its
    transport's shared-memory pool). A local subscriber maps the buffer; a remote one gets it over
    the network as before. The pool holds ``POOL_MESSAGES`` of the largest message; when it is full
    (subscribers still hold every buffer) the message is put as bytes, counted in ``fallbacks``.
    Not ``enabled``: every message is put as bytes."""

    POOL_MESSAGES = 4
    MIN_BYTES = 4096  # smaller messages are put as they are (Zenoh itself: 3 KB)

    def __init__(self, enabled: bool = True) -> None:
        self.enabled = enabled
        self._provider: Any = None
        self._pool_bytes = 0
        self.fallbacks = 0
        self.unlocated = 0  # buffers put without their location: subscribers copy them
        self.locator = Locator()  # where a buffer lies (its Zenoh segment)

    def payload(self, data: bytes | bytearray, restamp_now: bool = False) -> tuple[Any, bytes | None]:
        """(what to put for ``data``; its attachment): a shared-memory buffer for a large message,
        with its :class:`~sofia_runtime.shm.Location` as the attachment so that local subscribers
        read it in place, else the bytes. ``restamp_now``: the header stamp becomes the wall clock
        once the message's body is in place, just before the put (the publish time)."""
        buf = self.alloc(len(data)) if self.enabled and len(data) >= self.MIN_BYTES else None
        if buf is None:
            return (restamp_in_place(data, time.time_ns()) if restamp_now else data), None
        buf[:] = data
        head = bytes(data[:MARK])
        if restamp_now:
            header = restamp(bytes(data[:HEADER_BYTES]), time.time_ns())
            buf[:HEADER_BYTES] = header
            head = (header + head[HEADER_BYTES:])[:MARK]
        return buf, self.attachment(buf, len(data), head, bytes(data[-MARK:]))

    def attachment(
        self, buf: Any, size: int, head: bytes, tail: bytes, attachment: bytes | None = None
    ) -> bytes | None:
        """``attachment`` with the location of the message in ``buf`` (``size`` bytes from ``head`` to
        ``tail``) appended, when it can be told (see :class:`~sofia_runtime.shm.Locator`)."""
        location = self.locator.locate(buf, size, head, tail)
        if location is None:
            self.unlocated += 1
        return with_location(attachment, location)

    def alloc(self, size: int) -> Any:
        """A shared-memory buffer (``zenoh.shm.ZShmMut``) of ``size`` bytes from the pool, or None when
        every buffer is still held (counted in ``fallbacks``)."""
        from zenoh.shm import GarbageCollect, ShmProvider

        if self._provider is None or size * self.POOL_MESSAGES > self._pool_bytes:
            self._pool_bytes = size * self.POOL_MESSAGES
            self._provider = ShmProvider.default_backend(self._pool_bytes)
            log.info("Zenoh shared memory for messages: a pool of %.1f MB", self._pool_bytes / 1e6)
        try:
            return self._provider.alloc(size, GarbageCollect())
        except zenoh.ZError:  # every buffer still held by a subscriber
            self.fallbacks += 1
            return None


def shm_enabled(env: dict[str, str] | None = None) -> bool:
    """Whether this process may use Zenoh shared memory (``$SOFIA_ZENOH_SHM``, default on) and the
    installed Zenoh has it."""
    if not shm_wanted(env):
        return False
    try:
        import zenoh.shm  # noqa: F401 - built without the shared-memory feature: no provider
    except ImportError:
        return False
    return True
