"""Large messages read in place from Zenoh shared memory by a subscriber on the same host.

zenoh-python 1.10 gives a received shared-memory payload (``ZBytes.as_shm()``, a ``ZShm``) no
buffer protocol: ``to_bytes()`` copies it (1.2 ms for a 4.9 MB cloud). So the publisher says where
the message lies: the Zenoh segment file in ``/dev/shm`` and the offset in it, with the message's
first and last ``MARK`` bytes, appended to the sample's attachment (:func:`with_location`). A
subscriber on the same host maps that file read-only (:class:`SharedReader`) and reads the message
there, holding the sample's payload as long as any view of it lives: Zenoh does not hand a buffer
to its publisher again while a subscriber holds it.

Checked before use, else the payload is copied as before (``SharedReader.view`` returns None):
- publisher: its buffer's address (from the buffer's ``repr``) lies in one of its Zenoh segments
  and the bytes there are the message's first and last bytes (:func:`locate`);
- subscriber: the payload is shared memory, the segment is a ``*.zenoh`` file in ``/dev/shm`` that
  holds the whole message, and its first and last bytes are the ones the publisher saw.
"""

from __future__ import annotations

import ctypes
import logging
import mmap
import os
import re
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

import numpy as np

log = logging.getLogger(__name__)
SHM_DIR = "/dev/shm"
MARK = 16  # bytes compared at each end of a message
ADDRESS = re.compile(r"buf: PtrInSegment \{ ptr: 0x([0-9a-f]+) \}")  # in the repr of a ZShmMut
LOCATION_TAG = b"\nsofia.shm="  # starts the location at the end of an attachment
SEGMENTS_KEPT = 8  # segment files a reader keeps mapped (one publisher's pool is one segment)
_SEGMENT_NAME = re.compile(r"[0-9A-Za-z_.-]+\.zenoh")


@dataclass(frozen=True, slots=True)
class Location:
    """Where a message lies in shared memory: ``size`` bytes at ``offset`` of the segment file
    ``SHM_DIR/segment``, starting with ``head`` and ending with ``tail`` (``MARK`` bytes each)."""

    segment: str
    offset: int
    size: int
    head: bytes
    tail: bytes

    def encode(self) -> bytes:
        return f"{self.segment} {self.offset} {self.size} {self.head.hex()} {self.tail.hex()}".encode()

    @classmethod
    def parse(cls, text: bytes) -> Location | None:
        """The location in ``text`` (as :meth:`encode` writes it), None when it is not one."""
        try:
            segment, offset, size, head, tail = text.decode().split(" ")
            loc = cls(segment, int(offset), int(size), bytes.fromhex(head), bytes.fromhex(tail))
        except (UnicodeDecodeError, ValueError):
            return None
        ok = _SEGMENT_NAME.fullmatch(segment) and loc.offset >= 0 and loc.size >= 2 * MARK
        return loc if ok and len(loc.head) == len(loc.tail) == MARK else None


def with_location(attachment: bytes | None, location: Location | None) -> bytes | None:
    """``attachment`` with ``location`` appended (either may be None)."""
    if location is None:
        return attachment
    return (attachment or b"") + LOCATION_TAG + location.encode()


def split_location(attachment: bytes | None) -> tuple[bytes | None, Location | None]:
    """(the attachment without a location, the location or None); an attachment that was only a
    location gives None."""
    if attachment is None:
        return None, None
    rest, tag, text = bytes(attachment).rpartition(LOCATION_TAG)
    if not tag:
        return bytes(attachment), None
    return rest or None, Location.parse(text)


def zenoh_segments() -> list[tuple[int, int, str]]:
    """(start, end, path) of this process's mappings of Zenoh segments (``/dev/shm/*.zenoh``)."""
    ranges = []
    try:
        with open("/proc/self/maps") as maps:
            for line in maps:
                fields = line.split()
                if len(fields) >= 6 and fields[5].startswith(f"{SHM_DIR}/") and fields[5].endswith(".zenoh"):
                    start, end = fields[0].split("-")
                    if int(fields[2], 16) == 0:  # mapped from the file's start: offsets agree
                        ranges.append((int(start, 16), int(end, 16), fields[5]))
    except OSError:  # no /proc: no address can be checked
        pass
    return ranges


def buffer_address(buf: Any) -> int | None:
    """The address of a ``ZShmMut``'s bytes as its ``repr`` reports it (None: it does not)."""
    found = ADDRESS.search(repr(buf))
    return None if found is None else int(found.group(1), 16)


class Locator:
    """Publisher side: the :class:`Location` of a message written into a ``ZShmMut``."""

    def __init__(self) -> None:
        self._segments: list[tuple[int, int, str]] = []

    def locate(self, buf: Any, size: int, head: bytes, tail: bytes) -> Location | None:
        """Where ``buf`` (``size`` bytes, starting with ``head`` and ending with ``tail``) lies; None
        when its address is not reported, not in a mapped Zenoh segment or holds other bytes."""
        address = buffer_address(buf)
        if address is None or size < 2 * MARK:
            return None
        found = self.segment(address, size)
        if found is None:
            return None
        start, path = found
        if ctypes.string_at(address, MARK) != head or ctypes.string_at(address + size - MARK, MARK) != tail:
            return None
        return Location(os.path.basename(path), address - start, size, head, tail)

    def segment(self, address: int, size: int) -> tuple[int, str] | None:
        """(start, path) of this process's Zenoh segment holding ``size`` bytes at ``address``; None
        when none does (``/proc/self/maps`` is read again only when the known segments miss)."""
        found = self._known(address, size)
        if found is None:
            self._segments = zenoh_segments()
            found = self._known(address, size)
        return found

    def _known(self, address: int, size: int) -> tuple[int, str] | None:
        return next(((a, p) for a, b, p in self._segments if a <= address and address + size <= b), None)


class SharedReader:
    """Subscriber side: a read-only view of a received message in the segment its publisher named,
    or None (then copy the payload). ``read`` and ``copied`` count both; ``reason`` says why the
    last message was copied although it carried a location."""

    def __init__(self, enabled: bool = True) -> None:
        self.enabled = enabled
        self.read = 0
        self.copied = 0
        self.reason = ""
        self._segments: OrderedDict[str, tuple[mmap.mmap, int]] = OrderedDict()

    def received(self, sample: Any) -> tuple[bytes | memoryview, bytes | None]:
        """(the message of a ``zenoh.Sample``: read in place when its publisher said where, else
        copied; the sample's attachment without the location)."""
        rest, loc = split_location(None if sample.attachment is None else sample.attachment.to_bytes())
        view = self._view(sample.payload, loc)
        return sample.payload.to_bytes() if view is None else view, rest

    def view(self, payload: Any, attachment: bytes | None) -> memoryview | None:
        """The message of ``payload`` (a ``ZBytes``) as a read-only byte view that holds ``payload``;
        None when it must be copied (no location, not shared memory here, or a check failed)."""
        return self._view(payload, split_location(attachment)[1])

    def _view(self, payload: Any, loc: Location | None) -> memoryview | None:
        if loc is None or not self.enabled:
            return None
        if payload.as_shm() is None:
            self._copy("the payload is not in shared memory here")
            return None
        mapped = self._map(loc.segment)
        if mapped is None:
            return None
        mm, base = mapped
        if loc.offset + loc.size > len(mm):
            self._copy(f"{loc.size} bytes at {loc.offset} run past the {len(mm)}-byte segment {loc.segment}")
            return None
        arr = (ctypes.c_uint8 * loc.size).from_address(base + loc.offset)
        view = memoryview(arr).toreadonly()
        if view[:MARK] != loc.head or view[-MARK:] != loc.tail:
            self._copy(f"the bytes at {loc.offset} of {loc.segment} are not the message's")
            self._segments.pop(loc.segment, None)  # mapped again next time: a new file of that name?
            return None
        arr.held = (payload, mm)  # type: ignore[attr-defined]
        self.read += 1
        return view

    def _copy(self, reason: str) -> None:
        if reason != self.reason:
            log.warning("a shared-memory message is copied, not read in place: %s", reason)
        self.reason = reason
        self.copied += 1

    def _map(self, segment: str) -> tuple[mmap.mmap, int] | None:
        """The read-only mapping of ``SHM_DIR/segment`` and its address (kept for the next ones)."""
        if segment in self._segments:
            self._segments.move_to_end(segment)
            return self._segments[segment]
        try:
            fd = os.open(os.path.join(SHM_DIR, segment), os.O_RDONLY)
        except OSError as e:
            self._copy(f"cannot open the segment {segment}: {e}")
            return None
        try:
            mm = mmap.mmap(fd, 0, prot=mmap.PROT_READ)
        except (OSError, ValueError) as e:
            self._copy(f"cannot map the segment {segment}: {e}")
            return None
        finally:
            os.close(fd)
        while len(self._segments) >= SEGMENTS_KEPT:  # views still out hold their own mapping
            self._segments.popitem(last=False)
        self._segments[segment] = mapped = (mm, int(np.frombuffer(mm, np.uint8).ctypes.data))
        return mapped
