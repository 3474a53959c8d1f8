"""The dissipation plot explains itself, on the lab's real samples: every axis says its unit and
frame, before and after share one scale (and the result is shown again zoomed, said so), and a
panel shows how the flange poses turn about each base axis (what the observability advice is
about), with values that are the poses' own rotations from their mean."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sofia_calibrator.fitting.calibrate import calibrate
from sofia_calibrator.inputs.lab import read_lab
from sofia_calibrator.plot import plot_calibration

matplotlib.use("Agg")
LAB = Path(__file__).parents[2] / "data" / "lab"


def test_the_dissipation_plot_has_units_one_scale_and_the_poses_spread(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from matplotlib.figure import Figure

    p_cam, T_base_flange = read_lab(LAB / "poses.txt", LAB / "tfs.txt")
    cal = calibrate(p_cam, T_base_flange)
    figures: list[Any] = []
    save = Figure.savefig
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: (figures.append(fig), save(fig, *a, **k)))
    out = plot_calibration(cal, tmp_path / "dissipation.png")
    assert out.stat().st_size > 20_000
    axes = figures[0].axes
    assert len(axes) == 8
    for ax in axes:  # every label names its unit
        assert "(" in ax.get_xlabel() and "(" in ax.get_ylabel(), (
            ax.get_title(),
            ax.get_xlabel(),
            ax.get_ylabel(),
        )
    for axis in range(3):  # before and after on the same axes; the zoomed row says so
        assert len(axes[2 * axis].get_lines()) >= 2 and "before and after" in axes[2 * axis].get_title()
        assert "zoomed" in axes[2 * axis + 1].get_title()
    spread = next(ax for ax in axes if "how the poses turn" in ax.get_title())
    plotted = np.array([line.get_ydata() for line in spread.get_lines()[:3]]).T  # (n, 3) degrees
    R = Rotation.from_matrix(T_base_flange[:, :3, :3])
    expected = np.degrees((R.mean().inv() * R).as_rotvec())
    np.testing.assert_allclose(plotted, expected, atol=1e-9)
    assert np.ptp(plotted, axis=0).min() > 10.0  # the lab's poses turn about every base axis
