"""Sample files other than the lab's pair: CSV, JSON and Panda joint positions.

CSV: a header row naming the columns, one sample per row. Blob: ``px, py, pz`` (camera optical
frame, metres). Flange pose: either ``tx, ty, tz, qx, qy, qz, qw`` (base frame, quaternion x y z w)
or ``q1 .. q7`` (Panda joint positions, radians, through :func:`sofia_schemas.kinematics.panda_fk`).

JSON: a list of objects (or ``{"samples": [...]}``) each with ``p_cam`` and either ``translation`` +
``rotation_xyzw`` (the CalibrationSample fields) or ``q`` (7 joint positions).
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np
from sofia_schemas.kinematics import panda_fk
from sofia_schemas.transforms import make_transform

from ..errors import ParseError
from .lab import number_lines, parsed

POSE_COLUMNS = ("tx", "ty", "tz", "qx", "qy", "qz", "qw")
JOINT_COLUMNS = tuple(f"q{i}" for i in range(1, 8))
BLOB_COLUMNS = ("px", "py", "pz")


def _floats(path: Path, where: int | None, values: Any, n: int, what: str) -> np.ndarray:
    try:
        v = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParseError(path, where, f"{what} must be {n} numbers, got {values!r}") from None
    if v.shape != (n,):
        raise ParseError(path, where, f"{what} must be {n} numbers, got {values!r}")
    if not np.all(np.isfinite(v)):
        raise ParseError(path, where, f"{what} has non-finite values: {v.tolist()}")
    return v


def read_csv(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(p_cam (n, 3), T_base_flange (n, 4, 4)) from a CSV file (see the module docstring)."""
    path = Path(path)
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise ParseError(path, None, "no samples (need a header row and one row per sample)")
    cols = set(rows[0])
    missing = [c for c in BLOB_COLUMNS if c not in cols]
    has_pose, has_joints = set(POSE_COLUMNS) <= cols, set(JOINT_COLUMNS) <= cols
    if missing or not (has_pose or has_joints):
        raise ParseError(
            path, 1, f"header {sorted(cols)} must name {list(BLOB_COLUMNS)} and either "
            f"{list(POSE_COLUMNS)} or {list(JOINT_COLUMNS)}",
        )  # fmt: skip
    p = np.array(
        [_floats(path, i + 2, [r[c] for c in BLOB_COLUMNS], 3, "blob px py pz") for i, r in enumerate(rows)]
    )
    if has_pose:
        v = np.array(
            [_floats(path, i + 2, [r[c] for c in POSE_COLUMNS], 7, "pose") for i, r in enumerate(rows)]
        )
        return p, parsed(path, make_transform, v[:, :3], v[:, 3:])
    q = np.array(
        [_floats(path, i + 2, [r[c] for c in JOINT_COLUMNS], 7, "joints") for i, r in enumerate(rows)]
    )
    return p, parsed(path, panda_fk, q)


def read_json(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(p_cam (n, 3), T_base_flange (n, 4, 4)) from a JSON file (see the module docstring)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise ParseError(path, e.lineno, f"invalid JSON: {e.msg}") from None
    items = data.get("samples") if isinstance(data, dict) else data
    if not isinstance(items, list) or not items:
        raise ParseError(path, None, 'expected a non-empty list of samples (or {"samples": [...]})')
    p, t, q, joints = [], [], [], []
    for k, s in enumerate(items):
        if not isinstance(s, dict) or "p_cam" not in s:
            raise ParseError(path, None, f"sample {k} has no 'p_cam': {s!r}")
        p.append(_floats(path, None, s["p_cam"], 3, f"sample {k} p_cam"))
        if "q" in s:
            joints.append(_floats(path, None, s["q"], 7, f"sample {k} q"))
        elif "translation" in s and "rotation_xyzw" in s:
            t.append(_floats(path, None, s["translation"], 3, f"sample {k} translation"))
            q.append(_floats(path, None, s["rotation_xyzw"], 4, f"sample {k} rotation_xyzw"))
        else:
            raise ParseError(path, None, f"sample {k} needs 'translation' + 'rotation_xyzw' or 'q'")
    if joints and t:
        raise ParseError(path, None, "mix of joint ('q') and pose samples: use one kind per file")
    T = (
        parsed(path, panda_fk, np.array(joints))
        if joints
        else parsed(path, make_transform, np.array(t), np.array(q))
    )
    return np.array(p), T


def read_joints(path: str | Path) -> np.ndarray:
    """T_base_flange (n, 4, 4) from a file of Panda joint positions: 7 numbers per line, radians."""
    names = tuple(f"joint q{k}" for k in range(1, 8))
    return parsed(Path(path), panda_fk, number_lines(Path(path), names, "q1..q7", "joint positions"))


def read_samples(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """CSV or JSON by extension."""
    path = Path(path)
    if path.suffix.lower() == ".csv":
        return read_csv(path)
    if path.suffix.lower() == ".json":
        return read_json(path)
    raise ParseError(path, None, f"unknown sample file type {path.suffix!r}: use .csv or .json")
