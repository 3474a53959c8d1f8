"""Slider-crank and calibration table: round trips and known values."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from sofia_gripper import ConfigError, GripperConfig, load_config, save_config
from sofia_gripper.kinematics import OpeningTable, SliderCrank


@given(
    st.floats(5, 40), st.floats(1.5, 4.0), st.floats(-0.3, 0.3),
    st.lists(st.floats(0.01, 0.99), min_size=1, max_size=20),
)  # fmt: skip
def test_slider_crank_angle_inverts_travel(
    r: float, l_over_r: float, e_over_r: float, fractions: list[float]
) -> None:
    crank = SliderCrank(r, r * l_over_r + abs(e_over_r * r), e_over_r * r)
    low, high = crank.theta_range
    theta = low + np.array(fractions) * (high - low)
    travel = crank.travel(theta)
    np.testing.assert_allclose(crank.angle(travel), theta, atol=1e-6)


def test_slider_crank_known_positions() -> None:
    crank = SliderCrank(20.0, 50.0, 0.0)
    np.testing.assert_allclose(
        crank.travel([0.0, math.pi]), [0.0, 40.0], atol=1e-12
    )  # dead centres: 2 r apart
    np.testing.assert_allclose(crank.travel(math.pi / 2), 70.0 - math.sqrt(50.0**2 - 20.0**2))


def test_bad_geometry_and_tables_are_refused_with_the_values() -> None:
    with pytest.raises(ValueError, match=r"l=20"):
        SliderCrank(20.0, 20.0, 1.0)
    with pytest.raises(ValueError, match="decreasing opening"):
        OpeningTable([[0, 10], [5, 20]])
    with pytest.raises(ValueError, match=r"\(n>=2, 2\)"):
        OpeningTable([[0, 10, 3]])


def test_opening_round_trips_through_motor_ticks() -> None:
    kin = GripperConfig().kinematics()
    openings = np.linspace(0.0, 100.0, 41)
    np.testing.assert_allclose(kin.opening(kin.ticks(openings)), openings, atol=1e-9)
    c = GripperConfig()
    assert kin.opening(c.open_ticks) == pytest.approx(100.0, abs=0.1)
    assert kin.opening(c.closed_ticks) == pytest.approx(0.0, abs=0.1)


def test_config_file_round_trip_and_errors(tmp_path) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "gripper.yaml"
    conf = GripperConfig(port="/dev/ttyUSB1", open_ticks=1500, closed_ticks=2400)
    save_config(conf, path)
    assert load_config(path) == conf
    with pytest.raises(ConfigError, match="does not exist"):
        load_config(tmp_path / "missing.yaml")
    path.write_text("baud: -3\n")
    with pytest.raises(ConfigError, match="baud"):
        load_config(path)
    path.write_text("open_ticks: 3000\nclosed_ticks: 2000\n")
    with pytest.raises(ConfigError, match="open_ticks 3000 > closed_ticks 2000"):
        load_config(path)
