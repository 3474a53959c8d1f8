"""The detection picture explains itself: its title says what was found in words (never a bare
"ok" beside "NOT allowed"), every object's line names its field, whether it is picked and its
confidence, the fingertips of each grasp and the robot base's direction are drawn, and rows and
columns are numbered outside the board; `sofia detect --plot OUT.png` over several clouds numbers
the files like the scenes, OUT-01.png, OUT-02.png, ..."""

from __future__ import annotations

import subprocess
from pathlib import Path
from typing import Any

import matplotlib
import pytest
from sofia_detector import detect
from sofia_detector.plot import plot_detection
from sofia_replay.synth import write_scene_set
from sofia_schemas import Board

from ..conftest import SOFIA

matplotlib.use("Agg")


def texts_of_plot(monkeypatch: pytest.MonkeyPatch, *args: Any, **kwargs: Any) -> list[str]:
    """Every text the picture shows: title, legend, labels, annotations."""
    from matplotlib.figure import Figure

    seen: list[str] = []
    save = Figure.savefig

    def capture(fig: Figure, *a: Any, **k: Any) -> None:
        seen.extend(t.get_text() for t in fig.findobj(matplotlib.text.Text) if t.get_text())
        save(fig, *a, **k)

    monkeypatch.setattr(Figure, "savefig", capture)
    plot_detection(*args, **kwargs)
    return seen


def test_the_picture_says_what_was_found_in_words(scenes, board: Board, tmp_path: Path,  # type: ignore[no-untyped-def]
                                                  monkeypatch: pytest.MonkeyPatch) -> None:  # fmt: skip
    points = scenes["cylinder"].points_base
    det = detect(points, board)
    assert det.status == "ok" and det.objects
    texts = texts_of_plot(monkeypatch, points, board, det, tmp_path / "p.png", title="p: scene.npy, cloud 1")
    joined = "\n".join(texts)
    assert "p: scene.npy, cloud 1: 1 object(s) on the board" in texts
    assert "ok" not in joined.replace("object", "").split() and "NOT allowed" not in joined
    obj = det.objects[0]
    line = next(t for t in texts if t.startswith("1: "))
    assert f"row {obj.field[0]}, col {obj.field[1]}" in line and f"confidence {obj.confidence:.2f}" in line
    assert ("red field, to pick" if obj.allowed else "not a red field, not to pick") in line
    assert "fingertips of the grasp" in texts and "robot base" in texts
    assert {f"row {r}" for r in range(board.rows)} | {f"col {c}" for c in range(board.cols)} <= set(texts)
    assert any("height above the board (m)" in t for t in texts)
    assert (tmp_path / "p.png").stat().st_size > 20_000


def test_an_empty_board_is_said_so(scenes, board: Board, tmp_path: Path,  # type: ignore[no-untyped-def]
                                   monkeypatch: pytest.MonkeyPatch) -> None:  # fmt: skip
    points = scenes["empty"].points_base
    det = detect(points, board)
    assert det.status == "no_object"
    texts = texts_of_plot(monkeypatch, points, board, det, tmp_path / "e.png")
    assert "board seen, no object on it" in texts


def test_plots_of_several_clouds_are_numbered_like_the_scenes(tmp_path: Path) -> None:
    rec = tmp_path / "two.mcap"
    write_scene_set(rec, kind="one", n=2, seed=5, frames="base")
    r = subprocess.run([SOFIA, "detect", str(rec), "--plot", str(tmp_path / "board.png")],
                       capture_output=True, text=True, timeout=120)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in tmp_path.glob("board*.png")) == ["board-01.png", "board-02.png"]
