"""What the camera tells about itself, and the options' parsing: good values work, bad ones are
refused with the reason."""

from __future__ import annotations

import numpy as np
import pytest
from sofia_camera.device import device_info
from sofia_camera.errors import BadOption, UnsupportedMode
from sofia_camera.intrinsics import d435_spec
from sofia_camera.processing import parse_filters
from sofia_camera.sim_scene import SimOptions, SimWorld, parse_T_flange_cam
from sofia_camera.software import SoftwareCamera
from sofia_schemas.transforms import make_transform


def test_a_camera_lists_its_serial_firmware_and_usb_type() -> None:
    info = device_info(SoftwareCamera(serial="123456789").device)
    assert info["serial"] == "123456789" and info["firmware"] == "software" and info["usb_type"] == "none"


def test_filters_run_in_intels_order_and_unknown_ones_are_named() -> None:
    assert parse_filters("temporal,decimation") == ("decimation", "temporal")
    assert parse_filters("none") == () and parse_filters("") == ()
    with pytest.raises(BadOption, match="median"):
        parse_filters("spatial,median")


def test_only_the_d435_modes_are_accepted() -> None:
    assert d435_spec(1280, 720).color.fx == 920.0
    with pytest.raises(UnsupportedMode, match="1024x768"):
        d435_spec(1024, 768)


def test_T_flange_cam_from_numbers_or_a_file(tmp_path) -> None:  # type: ignore[no-untyped-def]
    T = parse_T_flange_cam("0.06, 0.0, 0.05, 0, 0, 0.7071068, 0.7071068")
    np.testing.assert_allclose(
        T, make_transform(np.array([0.06, 0, 0.05]), np.array([0, 0, 0.7071068, 0.7071068]))
    )
    f = tmp_path / "t.yaml"
    f.write_text(f"matrix: {T.tolist()}\n")
    np.testing.assert_allclose(parse_T_flange_cam(str(f)), T)
    with pytest.raises(BadOption, match="7 numbers"):
        parse_T_flange_cam("1 2 3")
    f.write_text("translation: [0, 0, 0]\n")
    with pytest.raises(BadOption, match="quaternion_xyzw"):
        parse_T_flange_cam(str(f))


def test_board_scene_is_deterministic_in_its_seed() -> None:
    a, b, c = (SimWorld(SimOptions(scene="board", seed=s)).truth() for s in (4, 4, 5))
    assert a == b and a["objects"] != c["objects"]
    with pytest.raises(BadOption, match="--sim-kind"):
        SimOptions(scene="board", kind="three")
