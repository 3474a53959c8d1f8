"""Where a cloud message is written: straight into a Zenoh shared-memory buffer, so that publishing it
copies nothing and a subscriber on the same host maps it (one on another host gets it over the
network as before).

Buffers come from the replayer's pool (:class:`~sofia_replay.preload.ShmBuffers`: a few messages of
the largest size, reused once subscribers drop them). zenoh-python 1.10 gives a ``ZShmMut`` no
buffer protocol, only slice assignment; the writer reaches its memory through the address Zenoh
reports for it, used only after checking that the address lies in one of this process's Zenoh
segments in ``/dev/shm`` and that bytes assigned through Zenoh read back there. When that check
fails the message is written into memory of its own and copied into the buffer once (``copied``);
when SHM is off or the pool is exhausted (every buffer still held) it is published as a plain put
(``fallbacks``). Each buffer's location goes with the cloud (:meth:`CloudBuffers.attachment`), so
that a local subscriber reads it in place (:mod:`sofia_runtime.shm`).
"""

from __future__ import annotations

import ctypes
import logging
import os
import secrets
from typing import Any

import numpy as np
import zenoh
from sofia_replay.preload import ShmBuffers
from sofia_runtime.shm import MARK as _MARK
from sofia_runtime.shm import SHM_DIR, buffer_address

log = logging.getLogger(__name__)
SHM_RESERVE = 16 << 20  # left free in /dev/shm: the size of Zenoh's own transport pool


def _shm_free() -> int | None:
    """Bytes free in ``/dev/shm`` (None: no such file system here)."""
    try:
        st = os.statvfs(SHM_DIR)
    except OSError:
        return None
    return st.f_bavail * st.f_frsize


class CloudBuffers:
    """Buffers of ``size`` bytes to write a message into, and what to put for it.

    enabled: False (``$SOFIA_ZENOH_SHM=off``, or a Zenoh without shared memory): every message is
    written into a ``bytearray`` and put as such. Also turned off (with a warning, ``detail`` says
    why) when ``/dev/shm`` has no room for the pool (a container's default is 64 MB) or Zenoh cannot
    create it.
    """

    def __init__(self, enabled: bool = True) -> None:
        self.pool = ShmBuffers(enabled)
        self.direct = 0  # messages written straight into shared memory
        self.copied = 0  # written beside it, then copied in (the buffer's address could not be checked)
        self._reachable = True  # False once a buffer's address failed its check: copy from then on
        self._spare = bytearray()
        self._copy_into: Any = None  # the buffer the spare's message goes into at ``ready``
        self._last: tuple[Any, np.ndarray] | None = None  # the last buffer taken, and its message
        self._checked_size = 0
        self._wanted = enabled
        self._refused = 0  # put as plain bytes because the pool could not be made
        self.detail = "" if enabled else "off"

    @property
    def enabled(self) -> bool:
        return self.pool.enabled

    @property
    def fallbacks(self) -> int:
        """Messages put as plain bytes although SHM is wanted: the pool was exhausted or not made."""
        return self.pool.fallbacks + self._refused

    def take(self, size: int) -> tuple[np.ndarray, Any]:
        """(view, payload): a writable (size,) uint8 array to write the message into, and the object to
        put once it is written (call :meth:`ready` first)."""
        self._copy_into = self._last = None
        if self.enabled and size != self._checked_size:
            self._check_room(size)
        try:
            buf = self.pool.alloc(size) if self.enabled and size >= ShmBuffers.MIN_BYTES else None
        except zenoh.ZError as e:  # the pool cannot be created
            self._turn_off(f"Zenoh cannot create a shared-memory pool: {e}")
            buf = None
        if buf is None:
            self._refused += self._wanted and not self.enabled and size >= ShmBuffers.MIN_BYTES
            data = bytearray(size)
            return np.frombuffer(data, np.uint8), data
        view = self._mapped(buf, size) if self._reachable else None
        if view is not None:
            self.direct += 1
        else:
            if len(self._spare) != size:
                self._spare = bytearray(size)
            self._copy_into = buf
            view = np.frombuffer(self._spare, np.uint8)
        self._last = buf, view
        return view, buf

    def ready(self, payload: Any) -> Any:
        """The payload to put once the view of the last :meth:`take` holds the message (a buffer whose
        memory could not be reached gets the message copied in now)."""
        if self._copy_into is not None and payload is self._copy_into:
            payload[:] = self._spare
            self.copied += 1
        self._copy_into = None
        return payload

    def attachment(self, payload: Any, attachment: bytes | None) -> bytes | None:
        """``attachment`` for ``payload``: with the location of its message appended when it is the
        shared-memory buffer of the last :meth:`take` (local subscribers then read it in place)."""
        if self._last is None or payload is not self._last[0]:
            return attachment
        view = self._last[1]
        return self.pool.attachment(
            payload, view.size, view[:_MARK].tobytes(), view[-_MARK:].tobytes(), attachment
        )

    def _check_room(self, size: int) -> None:
        self._checked_size = size
        need, free = size * ShmBuffers.POOL_MESSAGES, _shm_free()
        if free is not None and free < need + SHM_RESERVE:
            self._turn_off(f"{SHM_DIR} has {free / 1e6:.0f} MB free, a pool of {ShmBuffers.POOL_MESSAGES} "
                           f"clouds needs {need / 1e6:.0f} MB (+{SHM_RESERVE >> 20} MB kept free)")  # fmt: skip

    def _turn_off(self, reason: str) -> None:
        log.warning("clouds put as plain bytes, not from Zenoh shared memory: %s", reason)
        self.pool.enabled = False
        self.detail = reason

    def _mapped(self, buf: Any, size: int) -> np.ndarray | None:
        """The memory of ``buf`` as a writable uint8 array, or None when its address cannot be checked."""
        address = buffer_address(buf)
        if address is None or size < 2 * _MARK:
            return self._unreachable("this Zenoh does not report the buffer's address")
        if self.pool.locator.segment(address, size) is None:
            return self._unreachable(f"the buffer at {address:#x} is not in a mapped Zenoh segment")
        view = np.frombuffer(memoryview((ctypes.c_uint8 * size).from_address(address)).cast("B"), np.uint8)
        head, tail = secrets.token_bytes(_MARK), secrets.token_bytes(_MARK)
        buf[:_MARK] = head
        buf[size - _MARK : size] = tail
        if view[:_MARK].tobytes() != head or view[-_MARK:].tobytes() != tail:
            return self._unreachable(f"the buffer at {address:#x} does not read back")
        return view

    def _unreachable(self, reason: str) -> np.ndarray | None:
        """None (no view), after saying why: later buffers get their messages copied in."""
        log.warning("clouds written beside Zenoh shared memory and copied in: %s", reason)
        self._reachable = False
        self.detail = f"copied in: {reason}"
        return None
