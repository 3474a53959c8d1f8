"""Readers of the lab's sample files: ``poses.txt`` (blob x,y,z per line, camera frame, metres) and
``tfs.txt`` (flange poses in the base frame as ``translation:``/``rotation:`` blocks, x y z w)."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
from sofia_schemas.transforms import make_transform

from ..errors import InputMismatch, ParseError

_FIELD = re.compile(r"^\s*([xyzw])\s*:\s*(\S+)\s*$")
_SECTIONS = ("translation", "rotation")


def _float(path: Path, line_no: int, text: str, what: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ParseError(path, line_no, f"{what} {text!r} is not a number") from None
    if not np.isfinite(v):
        raise ParseError(path, line_no, f"{what} is {v}, expected a finite number")
    return v


def read_poses(path: str | Path) -> np.ndarray:
    """Blob positions from ``poses.txt``: one ``x,y,z`` line per sample. Returns (n, 3) metres."""
    return number_lines(Path(path), ("blob x", "blob y", "blob z"), "x,y,z", "samples")


def number_lines(path: Path, names: tuple[str, ...], columns: str, what: str) -> np.ndarray:
    """(n, len(names)) numbers of a text file, one row a line (commas or spaces between them; blank
    and ``#`` lines skipped). ParseError naming the line and the value that is wrong."""
    rows = []
    for i, line in enumerate(path.read_text().splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        parts = [p for p in re.split(r"[,\s]+", line.strip()) if p]
        if len(parts) != len(names):
            raise ParseError(
                path, i, f"expected {len(names)} comma-separated values {columns}, got {len(parts)}: {line!r}"
            )
        rows.append([_float(path, i, p, name) for p, name in zip(parts, names, strict=True)])
    if not rows:
        raise ParseError(path, None, f"no {what} (the file is empty)")
    return np.array(rows)


def read_tfs(path: str | Path) -> np.ndarray:
    """Flange poses from ``tfs.txt``. Returns (n, 4, 4) T_base_flange (quaternions x y z w)."""
    path = Path(path)
    blocks: list[dict[str, dict[str, float]]] = []
    section: str | None = None
    for i, line in enumerate(path.read_text().splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        head = s.rstrip(":").strip().lower()
        if head in _SECTIONS and s.endswith(":"):
            section = head
            if section == "translation" or not blocks:
                blocks.append({})
            if section in blocks[-1]:
                raise ParseError(path, i, f"second {section!r} in sample {len(blocks) - 1}")
            blocks[-1][section] = {}
            continue
        m = _FIELD.match(s)
        if m is None or section is None:
            raise ParseError(path, i, f"expected 'translation:', 'rotation:' or 'x: value', got {s!r}")
        axis, value = m.groups()
        if section == "translation" and axis == "w":
            raise ParseError(path, i, "translation has no 'w' component")
        blocks[-1][section][axis] = _float(path, i, value, f"{section} {axis}")
    if not blocks:
        raise ParseError(path, None, "no flange poses (the file is empty)")
    t = np.zeros((len(blocks), 3))
    q = np.zeros((len(blocks), 4))
    for k, b in enumerate(blocks):
        for section, axes, out in (("translation", "xyz", t), ("rotation", "xyzw", q)):
            got = b.get(section)
            if got is None or set(got) != set(axes):
                raise ParseError(
                    path, None, f"sample {k}: {section} needs {list(axes)}, got {sorted(got or [])}"
                )
            out[k] = [got[a] for a in axes]
    return parsed(path, make_transform, t, q)


def parsed(path: Path, build: Callable[..., np.ndarray], *args: np.ndarray) -> np.ndarray:
    """``build(*args)`` (the transforms of parsed numbers), its ValueError a ParseError naming ``path``."""
    try:
        return np.asarray(build(*args))
    except ValueError as e:
        raise ParseError(path, None, str(e)) from None


def read_lab(poses: str | Path, tfs: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(p_cam (n, 3), T_base_flange (n, 4, 4)) from the lab's pair of files; counts must match."""
    p_cam, T = read_poses(poses), read_tfs(tfs)
    if len(p_cam) != len(T):
        raise InputMismatch(f"{poses} has {len(p_cam)} blob positions but {tfs} has {len(T)} flange poses")
    return p_cam, T
