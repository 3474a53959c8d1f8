"""The calibrator's samples and their append-only log (``samples.jsonl``), replayed on restart.

Every change is one checksummed line (see :mod:`.sample_log`), fsynced before it is acknowledged;
a refused change leaves nothing on disk. On start a torn tail is cut off and kept aside, and each
damaged line is skipped, kept aside, counted and named in a warning: the rest loads.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np
from sofia_schemas.messages.calibration import CalibrationSample
from sofia_schemas.transforms import make_transform

from .sample_checks import check_sample
from .sample_errors import SampleLogError, UnknownSamples
from .sample_log import Appender, Damaged, decode, encode, keep_damaged, recover

log = logging.getLogger(__name__)
LOG_NAME = "samples.jsonl"


def _short(value: object) -> str:
    text = value if isinstance(value, str) else repr(value)
    return text if len(text) <= 60 else f"{text[:60]}... ({len(text)} characters)"


class SampleStore:
    """Samples by id; every change is appended (and fsynced) to ``state_dir/samples.jsonl``.

    ``generation`` grows with every change, so a result can be matched to the samples it used.
    """

    def __init__(self, state_dir: str | Path) -> None:
        self.dir = Path(state_dir)
        self.path = self.dir / LOG_NAME
        self.samples: dict[int, CalibrationSample] = {}
        self.next_id = 0
        self.generation = 0
        self.damaged: list[Damaged] = []
        self.recent: list[Damaged] = []  # damaged lines since the last reset: they still matter
        self.unchecked = 0  # lines of an older log, without a checksum
        self.torn_bytes = 0
        self.write_errors = 0
        try:
            self.dir.mkdir(parents=True, exist_ok=True)
            if self.path.exists():
                self._replay()
            self._log = Appender(self.path)
        except OSError as e:
            raise SampleLogError(self.path, f"cannot open the sample log: {e.strerror or e}") from None

    def _replay(self) -> None:
        size = self.path.stat().st_size
        lines = recover(self.path)
        self.torn_bytes = size - self.path.stat().st_size
        if self.torn_bytes:
            log.warning("%s: cut a torn last line of %d bytes (kept in %s.torn)", self.path, self.torn_bytes,
                        self.path)  # fmt: skip
        seen_checked = False
        for line in lines:
            if not line.raw.strip():
                continue
            try:
                entry, checked = decode(line.raw)
                if seen_checked and not checked:
                    raise ValueError("no checksum, after lines with one")
                self._apply(entry)
            except Exception as e:  # any damage (bad bytes, overflow, deep nesting): skip this line only
                self._skip(Damaged(line.number, line.raw, f"{type(e).__name__}: {_short(str(e))}"))
                continue
            seen_checked |= checked
            self.unchecked += not checked
        if self.damaged:
            side = keep_damaged(self.path, self.damaged)
            log.warning("%s: %d damaged line(s) skipped (copies in %s)", self.path, len(self.damaged), side)
        if self.unchecked:
            log.warning("%s: %d line(s) without checksum (an older log), read unchecked", self.path,
                        self.unchecked)  # fmt: skip
        log.info("resumed %d samples from %s", len(self.samples), self.path)

    def _skip(self, d: Damaged) -> None:
        self.damaged.append(d)
        self.recent.append(d)
        what = f"sample {d.sample_id} lost" if d.sample_id is not None else f"op {d.op}"
        log.warning("%s:%d skipped (%s): %s", self.path, d.number, what, d.reason)

    def _apply(self, entry: dict[str, Any]) -> None:
        """Apply one replayed record; raises ValueError naming what is wrong (nothing applied)."""
        op, members = entry.get("op"), sorted(entry)
        if op == "add" and members == ["op", "sample"]:
            s = CalibrationSample.model_validate(entry["sample"])
            if s.sample_id is None or s.sample_id < 0:
                raise ValueError(f"add record without a sample_id: {_short(entry['sample'])}")
            if s.sample_id in self.samples:
                raise ValueError(f"sample {s.sample_id} added a second time")
            check_sample(s)
            self.samples[s.sample_id] = s
            self.next_id = max(self.next_id, s.sample_id + 1)
        elif op == "remove" and members in (["op", "sample_ids"], ["op", "sample_id"]):
            ids = entry.get("sample_ids", [entry.get("sample_id")])
            if not isinstance(ids, list) or not all(type(i) is int for i in ids):
                raise ValueError(f"remove record with ids {_short(ids)}")
            absent = [i for i in ids if i not in self.samples]
            if absent:
                log.warning("%s: remove of absent sample(s) %s", self.path, absent)
            for i in ids:
                self.samples.pop(i, None)
        elif op == "reset" and members == ["op"]:
            self.samples.clear()
            self.recent.clear()  # nothing before a reset matters any more
        else:
            raise ValueError(f"not a record: op {_short(op)} with members {_short(members)}")
        self.generation += 1

    def _write(self, entry: dict[str, Any]) -> None:
        try:
            self._log.append(encode(entry))
        except SampleLogError:
            self.write_errors += 1
            raise

    def add(self, sample: CalibrationSample) -> CalibrationSample:
        """Store ``sample`` under the next id once its line is durable; refuse an implausible one."""
        check_sample(sample.model_copy(update={"sample_id": None}))
        s = sample.model_copy(update={"sample_id": self.next_id})
        self._write({"op": "add", "sample": s.model_dump(mode="json")})
        self.samples[self.next_id] = s
        self.next_id += 1
        self.generation += 1
        return s

    def remove(self, sample_ids: list[int]) -> None:
        """Remove every sample of ``sample_ids`` in one record, or none if any id is unknown."""
        ids = list(dict.fromkeys(sample_ids))
        missing = [i for i in ids if i not in self.samples]
        if missing:
            raise UnknownSamples(missing, sorted(self.samples))
        if not ids:
            return
        self._write({"op": "remove", "sample_ids": ids})
        for i in ids:
            del self.samples[i]
        self.generation += 1

    def reset(self) -> None:
        self._write({"op": "reset"})
        self.samples.clear()
        self.recent.clear()
        self.generation += 1

    def suspect(self) -> list[Damaged]:
        """Damaged lines since the last reset that may have been a remove or a reset: while there
        are any, the samples may be inconsistent (a removed sample may be back)."""
        return [d for d in self.recent if d.op != "add"]

    def problems(self) -> list[str]:
        """What is wrong with the log, for the service's status (empty when nothing is)."""
        out = []
        if suspect := self.suspect():
            where = ", ".join(f"{self.path.name}:{d.number}" for d in suspect[:5])
            out.append(f"samples may be inconsistent: damaged line(s) {where} may have removed samples "
                       "(check the samples, then remove or reset)")  # fmt: skip
        lost = [d.sample_id for d in self.recent if d.sample_id is not None]
        if lost:
            out.append(f"sample(s) {lost[:10]} lost to damaged lines")
        if self.recent:
            out.append(f"{len(self.recent)} damaged line(s) skipped, copies in {self.path}.damaged")
        if self._log.broken:
            out.append(f"sample log not writable: {self._log.broken}")
        return out

    def counters(self) -> dict[str, int]:
        return {"damaged_lines": len(self.damaged), "unchecked_lines": self.unchecked,
                "torn_bytes": self.torn_bytes, "write_errors": self.write_errors}  # fmt: skip

    def ordered(self) -> list[CalibrationSample]:
        return [self.samples[k] for k in sorted(self.samples)]

    def arrays(self) -> tuple[np.ndarray, np.ndarray, list[int]]:
        """(p_cam (n, 3), T_base_flange (n, 4, 4), sample ids) in id order."""
        s = self.ordered()
        if not s:
            return np.zeros((0, 3)), np.zeros((0, 4, 4)), []
        p = np.array([x.p_cam for x in s])
        T = make_transform(np.array([x.translation for x in s]), np.array([x.rotation_xyzw for x in s]))
        return p, T.reshape(-1, 4, 4), [int(x.sample_id or 0) for x in s]

    def close(self) -> None:
        self._log.close()
