"""The calibrator's sample database (``samples.db``): SQLite through the standard library.

WAL journal, ``synchronous=FULL``, one transaction per acknowledged operation; ids from an
``AUTOINCREMENT`` key are never given twice (removal, reset, crash). On open ``PRAGMA
integrity_check`` runs; a database that fails it (or is not one) is moved aside with its WAL
(``samples.db.corrupt-<time>``) and a new one started: :class:`Opened` says what was found and
holds the rows still readable from the damaged file.
"""

from __future__ import annotations

import logging
import os
import sqlite3
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypeVar

from .durable import fsync_dir
from .errors import SampleLogError

T = TypeVar("T")
log = logging.getLogger(__name__)
SCHEMA = """
CREATE TABLE IF NOT EXISTS samples (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    body TEXT NOT NULL  -- the CalibrationSample as JSON, its sample_id included
);
CREATE TABLE IF NOT EXISTS notes (  -- what went wrong with the samples, kept until a reset
    id INTEGER PRIMARY KEY,
    text TEXT NOT NULL
);
"""
NEXT_ID = "COALESCE((SELECT seq FROM sqlite_sequence WHERE name = 'samples'), -1) + 1"  # ids from 0
SIDE_FILES = ("", "-wal", "-shm")


@dataclass
class Opened:
    """What opening the database found: ``corrupt`` (why, empty if sound), ``kept_aside`` (where
    the damaged file went) and ``salvaged`` rows ``(id, body)`` read from it before it was moved."""

    corrupt: str = ""
    kept_aside: Path | None = None
    salvaged: list[tuple[int, str]] = field(default_factory=list)
    next_id: int = 0  # one more than the highest id the damaged file had given, if still readable


def _connect(path: Path) -> sqlite3.Connection:
    conn = sqlite3.connect(path, isolation_level=None, check_same_thread=False, timeout=5.0)
    conn.execute("PRAGMA journal_mode=WAL")
    conn.execute("PRAGMA synchronous=FULL")
    return conn


def _check(path: Path) -> Opened:
    """What is wrong with the database at ``path`` (nothing: ``corrupt`` empty), the rows and the
    next id still readable from it if something is."""
    rows: list[tuple[int, str]] = []
    next_id = 0
    try:
        conn = sqlite3.connect(path, isolation_level=None)
        try:
            found = [r[0] for r in conn.execute("PRAGMA integrity_check(20)")]
            problem = "" if found == ["ok"] else "; ".join(found)
            if problem:
                try:
                    next_id = int(conn.execute(f"SELECT {NEXT_ID}").fetchone()[0])
                    rows = [
                        (int(i), str(b)) for i, b in conn.execute("SELECT id, body FROM samples ORDER BY id")
                    ]
                except (sqlite3.DatabaseError, ValueError, TypeError) as e:
                    log.warning("%s: rows not readable from the damaged database: %s", path, e)
        finally:
            conn.close()
    except sqlite3.OperationalError:  # cannot open or read it (a directory, no permission): not damage
        raise
    except sqlite3.DatabaseError as e:  # "file is not a database", "database disk image is malformed"
        problem = f"{e}"
    return Opened(problem, None, rows, next_id)


def _keep_aside(path: Path) -> Path:
    stamp = time.strftime("%Y%m%dT%H%M%S")
    kept = path.with_name(f"{path.name}.corrupt-{stamp}")
    for suffix in SIDE_FILES:
        src = Path(f"{path}{suffix}")
        if src.exists():
            os.replace(src, Path(f"{kept}{suffix}"))
    fsync_dir(path.parent)
    return kept


class SampleDb:
    """The ``samples`` table of ``path``; every method is one transaction (raises
    :class:`SampleLogError` naming the file when SQLite refuses, nothing changed)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.opened = Opened()
        try:
            if path.exists() and not path.is_file():
                raise OSError(f"{path} is not a file")
            if path.exists():
                found = _check(path)
                if found.corrupt:
                    found.kept_aside = _keep_aside(path)
                    self.opened = found
                    log.error("%s failed its integrity check (%s): kept aside as %s, %d rows still readable",
                              path, found.corrupt, found.kept_aside, len(found.salvaged))  # fmt: skip
            created = not path.exists()
            self.conn = _connect(path)
            self.conn.executescript(SCHEMA)
            if created:
                fsync_dir(path.parent)
        except (sqlite3.Error, OSError) as e:
            raise SampleLogError(path, f"cannot open the sample database: {e}") from None

    def rows(self) -> list[tuple[int, str]]:
        """Every ``(id, body)`` in id order."""
        return [(int(i), str(b)) for i, b in self.conn.execute("SELECT id, body FROM samples ORDER BY id")]

    def next_id(self) -> int:
        return int(self.conn.execute(f"SELECT {NEXT_ID}").fetchone()[0])

    def add(self, body_of: Callable[[int], str]) -> int:
        """Insert the sample ``body_of(id)`` (the body names its own id); returns the id."""

        def insert(conn: sqlite3.Connection) -> int:
            new_id = int(conn.execute(f"SELECT {NEXT_ID}").fetchone()[0])
            conn.execute("INSERT INTO samples (id, body) VALUES (?, ?)", (new_id, body_of(new_id)))
            return new_id

        return self._transaction("add", insert)

    def insert_many(self, rows: Iterable[tuple[int, str]], next_id: int) -> None:
        """Insert ``rows`` with their own ids, and make ``next_id`` the lowest id ever given next."""

        def insert(conn: sqlite3.Connection) -> None:
            conn.executemany("INSERT INTO samples (id, body) VALUES (?, ?)", rows)
            if next_id > 0:  # ids up to next_id - 1 were given before: never again
                if conn.execute("SELECT 1 FROM sqlite_sequence WHERE name = 'samples'").fetchone():
                    conn.execute("UPDATE sqlite_sequence SET seq = MAX(seq, ?) WHERE name = 'samples'",
                                 (next_id - 1,))  # fmt: skip
                else:
                    conn.execute(
                        "INSERT INTO sqlite_sequence (name, seq) VALUES ('samples', ?)", (next_id - 1,)
                    )

        self._transaction("import", insert)

    def notes(self) -> list[str]:
        return [str(t) for (t,) in self.conn.execute("SELECT text FROM notes ORDER BY id")]

    def note(self, text: str) -> None:
        self._transaction("note", lambda c: c.execute("INSERT INTO notes (text) VALUES (?)", (text,)))

    def remove(self, ids: list[int]) -> None:
        self._transaction(
            "remove", lambda c: c.executemany("DELETE FROM samples WHERE id = ?", [(i,) for i in ids])
        )

    def reset(self) -> None:
        self._transaction("reset", lambda c: c.execute("DELETE FROM samples").execute("DELETE FROM notes"))

    def _transaction(self, what: str, work: Callable[[sqlite3.Connection], T]) -> T:
        conn = self.conn
        try:
            conn.execute("BEGIN IMMEDIATE")
            try:
                out = work(conn)
                conn.execute("COMMIT")
            except BaseException:
                if conn.in_transaction:
                    conn.execute("ROLLBACK")
                raise
        except sqlite3.Error as e:
            raise SampleLogError(self.path, f"{what} failed, nothing written: {e}") from None
        return out

    def close(self) -> None:
        self.conn.close()
