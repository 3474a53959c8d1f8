"""Keep a service's resident memory bounded after bursts (glibc's heap, through ``ctypes``).

Under overload or fuzzing, payloads of every size are allocated and freed on Zenoh's many threads.
By default glibc gives each thread its own arena (up to 8 per core) and keeps freed memory inside
them, so the resident size only ratchets up. Two settings bound it:

- :func:`bound_heap`: at most ``ARENAS`` arenas (``mallopt(M_ARENA_MAX)``, what ``MALLOC_ARENA_MAX``
  sets); call it before threads start (the ``sofia`` command does, first thing);
- :func:`trim_heap`: hand free pages of every arena back to the system (``malloc_trim(0)``);
  :class:`~sofia_runtime.service.StatusEndpoint` calls it once a second.

On a C library other than glibc both do nothing.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
from pathlib import Path

ARENAS = 2
M_ARENA_MAX = -8  # glibc's malloc.h
_PAGE = os.sysconf("SC_PAGE_SIZE")


def _libc() -> ctypes.CDLL | None:
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
    except OSError:
        return None
    return libc if hasattr(libc, "malloc_trim") and hasattr(libc, "mallopt") else None


_LIBC = _libc()


def bound_heap(arenas: int = ARENAS) -> bool:
    """Limit glibc to ``arenas`` malloc arenas; False when not on glibc (or refused)."""
    return bool(_LIBC is not None and _LIBC.mallopt(M_ARENA_MAX, arenas) == 1)


def trim_heap() -> bool:
    """Return free heap pages to the system; True when memory was released."""
    return bool(_LIBC is not None and _LIBC.malloc_trim(0) == 1)


def rss_bytes(pid: int | str = "self") -> int:
    """Resident set size of process ``pid`` (this one by default), in bytes (from /proc)."""
    return int(Path(f"/proc/{pid}/statm").read_text().split()[1]) * _PAGE
