"""Reading a JSONL sample log (``samples.jsonl``, before the SQLite database) for its import
(:mod:`.log`: format and side files): a torn tail is cut off and kept aside; each damaged line is
skipped, kept aside, counted and named in a warning; the rest loads.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sofia_schemas.messages.calibration import CalibrationSample

from .checks import check_sample
from .log import Damaged, decode, keep_damaged, recover

log = logging.getLogger(__name__)


def short(value: object) -> str:
    text = value if isinstance(value, str) else repr(value)
    return text if len(text) <= 60 else f"{text[:60]}... ({len(text)} characters)"


@dataclass
class JsonlLog:
    """The samples a JSONL log leaves, and what was wrong with it."""

    path: Path
    samples: dict[int, CalibrationSample] = field(default_factory=dict)
    next_id: int = 0  # one more than the highest id the log ever gave
    damaged: list[Damaged] = field(default_factory=list)
    recent: list[Damaged] = field(default_factory=list)  # damaged lines after the last reset
    unchecked: int = 0  # lines of an older log, without a checksum
    torn_bytes: int = 0

    def read(self) -> JsonlLog:
        size = self.path.stat().st_size
        lines = recover(self.path)
        self.torn_bytes = size - self.path.stat().st_size
        if self.torn_bytes:
            log.warning("%s: cut a torn last line of %d bytes (kept in %s.torn)", self.path, self.torn_bytes,
                        self.path)  # fmt: skip
        seen_checked = False
        for number, raw in lines:
            if not raw.strip():
                continue
            try:
                entry, checked = decode(raw)
                if seen_checked and not checked:
                    raise ValueError("no checksum, after lines with one")
                self._apply(entry)
            except Exception as e:  # any damage (bad bytes, overflow, deep nesting): skip this line only
                self._skip(Damaged(number, raw, f"{type(e).__name__}: {short(str(e))}"))
                continue
            seen_checked |= checked
            self.unchecked += not checked
        if self.damaged:
            side = keep_damaged(self.path, self.damaged)
            log.warning("%s: %d damaged line(s) skipped (copies in %s)", self.path, len(self.damaged), side)
        if self.unchecked:
            log.warning("%s: %d line(s) without checksum (an older log), read unchecked", self.path,
                        self.unchecked)  # fmt: skip
        return self

    def _skip(self, d: Damaged) -> None:
        if d.sample_id is not None:  # a damaged add was acknowledged once: its id is never given again
            self.next_id = max(self.next_id, d.sample_id + 1)
        self.damaged.append(d)
        self.recent.append(d)
        what = f"sample {d.sample_id} lost" if d.sample_id is not None else f"op {d.op}"
        log.warning("%s:%d skipped (%s): %s", self.path, d.number, what, d.reason)

    def _apply(self, entry: dict[str, Any]) -> None:
        """Apply one record; raises ValueError naming what is wrong (nothing applied)."""
        op, members = entry.get("op"), sorted(entry)
        if op == "add" and members == ["op", "sample"]:
            s = CalibrationSample.model_validate(entry["sample"])
            if s.sample_id is None or s.sample_id < 0:
                raise ValueError(f"add record without a sample_id: {short(entry['sample'])}")
            if s.sample_id in self.samples:
                raise ValueError(f"sample {s.sample_id} added a second time")
            check_sample(s)
            self.samples[s.sample_id] = s
            self.next_id = max(self.next_id, s.sample_id + 1)
        elif op == "remove" and members in (["op", "sample_ids"], ["op", "sample_id"]):
            ids = entry.get("sample_ids", [entry.get("sample_id")])
            if not isinstance(ids, list) or not all(type(i) is int for i in ids):
                raise ValueError(f"remove record with ids {short(ids)}")
            absent = [i for i in ids if i not in self.samples]
            if absent:
                log.warning("%s: remove of absent sample(s) %s", self.path, absent)
            for i in ids:
                self.samples.pop(i, None)
        elif op == "reset" and members == ["op"]:
            self.samples.clear()
            self.recent.clear()  # nothing before a reset matters any more
        else:
            raise ValueError(f"not a record: op {short(op)} with members {short(members)}")
