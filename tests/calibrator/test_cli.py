"""``sofia calibrate`` for people: the lab's files in, JSON / YAML / plot out, clear errors."""

from __future__ import annotations

import json
import subprocess
from importlib.metadata import entry_points
from pathlib import Path

import numpy as np
import pytest
import yaml
from sofia_calibrator import cli, to_message, to_yaml
from sofia_calibrator.cli import CALIBRATE_MODES
from sofia_calibrator.fitting.calibrate import calibrate
from sofia_calibrator.fitting.simulate import make_problem

from ..conftest import SOFIA

KEYS = ("matrix", "translation", "quaternion_xyzw", "rpy", "target_base", "spread_mm", "inliers", "outliers",
        "std_translation_mm", "std_rotation_deg", "dissipation_before", "dissipation_after", "warnings")  # fmt: skip


def sofia(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([SOFIA, *args], capture_output=True, text=True, timeout=120)


def test_calibrate_lab_json_and_plot(lab_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "dissipation.png"
    r = sofia("calibrate", "--poses", str(lab_dir / "poses.txt"), "--tfs", str(lab_dir / "tfs.txt"),
              "--json", "--plot", str(out), "--yaml", str(tmp_path / "cal.yaml"))  # fmt: skip
    assert r.returncode == 0, r.stderr
    body = json.loads(r.stdout)
    assert all(k in body for k in KEYS)
    assert body["outliers"] == [] and body["inliers"] == list(range(11)) and body["passes"]
    assert max(body["spread_mm"]) < 10.0 and body["with_all_samples"] is None
    corr = body["camera_correction"]
    assert (
        corr["model"] == "depth_scale"
        and 0.94 <= corr["depth_scale"] <= 0.96
        and corr["depth_scale_sigma"] > 0
    )
    assert [c["model"] for c in body["correction_models"] if c["chosen"]] == ["depth_scale"]
    cov = np.array(body["covariance"])
    assert cov.shape == (6, 6) and np.allclose(cov, cov.T) and np.all(np.linalg.eigvalsh(cov) > 0)
    np.testing.assert_allclose(1e3 * np.sqrt(np.diag(cov)[:3]), body["std_translation_mm"], rtol=1e-6)
    assert 0.5 < body["noise_mm"] < 3.0
    assert np.allclose(np.array(body["matrix"])[:3, 3], body["translation"])
    assert "panda_link8 camera_color_optical_frame" in body["ros1_static_transform"]
    assert out.stat().st_size > 20_000 and out.read_bytes()[:4] == b"\x89PNG"
    doc = yaml.safe_load((tmp_path / "cal.yaml").read_text())
    assert doc["camera_correction"]["model"] == "depth_scale"
    np.testing.assert_allclose(doc["covariance"], cov, rtol=1e-3, atol=1e-12)
    assert doc["noise_mm"] == pytest.approx(body["noise_mm"], rel=1e-6)
    assert "reads 5." in (tmp_path / "cal.yaml").read_text()  # what the correction means, in words


def test_calibrate_with_guess_gives_the_same_answer(lab_dir: Path) -> None:
    base = ["calibrate", "--poses", str(lab_dir / "poses.txt"), "--tfs", str(lab_dir / "tfs.txt"), "--json"]
    a = json.loads(sofia(*base).stdout)
    b = json.loads(sofia(*base, "--guess", "0.1", "0", "0.05", "-0.2", "-0.2", "0.67", "0.68").stdout)
    np.testing.assert_allclose(a["matrix"], b["matrix"], atol=1e-6)
    bad = sofia(*base, "--guess", "0", "0", "0", "0", "0", "0", "2")
    assert bad.returncode == 2 and "norm 2.0" in bad.stderr


def test_calibrate_errors_are_one_clear_line(tmp_path: Path, lab_dir: Path) -> None:
    r = sofia("calibrate", "--poses", str(tmp_path / "missing.txt"), "--tfs", str(lab_dir / "tfs.txt"))
    assert r.returncode == 2 and "missing.txt" in r.stderr and "Traceback" not in r.stderr
    (tmp_path / "poses.txt").write_text("0.1,0.2,0.5\n")
    r = sofia("calibrate", "--poses", str(tmp_path / "poses.txt"), "--tfs", str(lab_dir / "tfs.txt"))
    assert r.returncode == 2 and "1 blob positions but" in r.stderr
    r = sofia("calibrate")
    assert r.returncode == 2 and "give --poses" in r.stderr


def test_calibrate_from_mcap(tmp_path: Path) -> None:
    from sofia_replay.synth.record import write_calibration_session

    session = write_calibration_session(tmp_path / "c.mcap", n_poses=6, seed=2, clouds=False)
    r = sofia("calibrate", "--mcap", str(tmp_path / "c.mcap"), "--json")
    assert r.returncode == 0, r.stderr
    body = json.loads(r.stdout)
    assert np.linalg.norm(np.array(body["translation"]) - session.T_flange_cam[:3, 3]) < 0.005


def test_calibrate_from_mcap_clouds(tmp_path: Path) -> None:
    from sofia_replay.synth.record import write_calibration_session

    session = write_calibration_session(tmp_path / "c.mcap", n_poses=6, seed=3, clouds=True)
    r = sofia("calibrate", "--mcap", str(tmp_path / "c.mcap"), "--from-clouds", "--json")
    assert r.returncode == 0, r.stderr
    body = json.loads(r.stdout)
    assert np.linalg.norm(np.array(body["translation"]) - session.T_flange_cam[:3, 3]) < 0.005


def test_yaml_and_ros_lines_name_the_direction() -> None:
    pr = make_problem(8, np.random.default_rng(1))
    msg = to_message(calibrate(pr.p_cam, pr.T_base_flange))
    text = to_yaml(msg)
    assert text.startswith("# T_flange_cam: maps points in the camera optical frame into the flange frame")
    t, q = msg.translation, msg.quaternion_xyzw
    assert (
        f'args="{t[0]:.6f} {t[1]:.6f} {t[2]:.6f} {q[0]:.6f} {q[1]:.6f} {q[2]:.6f} {q[3]:.6f} panda_link8 camera_color_optical_frame 100"'
        in msg.ros1_static_transform
    )
    assert (
        f"--qw {q[3]:.6f} --frame-id panda_link8 --child-frame-id camera_color_optical_frame"
        in msg.ros2_static_transform
    )
    np.testing.assert_allclose(msg.matrix, pr.T_flange_cam, atol=0.01)


def test_calibrate_from_joints(tmp_path: Path) -> None:
    from sofia_schemas.kinematics import panda_fk

    rng = np.random.default_rng(0)
    q = np.array([0.0, -0.5, 0.0, -2.2, 0.0, 1.9, 0.8]) + rng.uniform(-0.35, 0.35, (10, 7))
    T_fc = make_problem(3, rng).T_flange_cam
    T_base_cam = panda_fk(q) @ T_fc
    p_base = T_base_cam[0, :3, 3] + 0.4 * T_base_cam[0, :3, 2]
    p_cam = np.einsum("nji,nj->ni", T_base_cam[:, :3, :3], p_base - T_base_cam[:, :3, 3])
    (tmp_path / "joints.txt").write_text("\n".join(" ".join(f"{v:.17g}" for v in r) for r in q) + "\n")
    (tmp_path / "poses.txt").write_text("\n".join(",".join(f"{v:.17g}" for v in r) for r in p_cam) + "\n")
    r = sofia(
        "calibrate",
        "--poses",
        str(tmp_path / "poses.txt"),
        "--joints",
        str(tmp_path / "joints.txt"),
        "--json",
    )
    assert r.returncode == 0, r.stderr
    np.testing.assert_allclose(json.loads(r.stdout)["matrix"], T_fc, atol=1e-6)


def test_frames_are_options_and_a_w_first_guess_is_one_more_start(lab_dir: Path) -> None:
    base = ["calibrate", "--poses", str(lab_dir / "poses.txt"), "--tfs", str(lab_dir / "tfs.txt"), "--json"]
    a = json.loads(sofia(*base).stdout)
    # "0 0 0 1 0 0 0" typed w first is a 180-degree turn in x y z w: the closed form still wins
    r = sofia(*base, "--guess", "0", "0", "0", "1", "0", "0", "0", "--parent-frame", "fr3_link8",
              "--child-frame", "cam_optical")  # fmt: skip
    assert r.returncode == 0, r.stderr
    b = json.loads(r.stdout)
    np.testing.assert_allclose(a["matrix"], b["matrix"], atol=1e-6)
    assert b["inliers"] == list(range(11)) and b["passes"]
    assert b["parent_frame"] == "fr3_link8" and b["child_frame"] == "cam_optical"
    assert "fr3_link8 cam_optical 100" in b["ros1_static_transform"]
    assert "--frame-id fr3_link8 --child-frame-id cam_optical" in b["ros2_static_transform"]
    assert a["parent_frame"] == "panda_link8" and a["child_frame"] == "camera_color_optical_frame"


def test_calibrate_auto_comes_from_the_arm_through_an_entry_point() -> None:
    """`sofia calibrate auto` is the arm's mode, registered in the ``sofia.calibrate_modes`` group;
    the calibrator's CLI imports nothing of the arm (the layers contract checks the source)."""
    modes = {ep.name: ep.value for ep in entry_points(group=CALIBRATE_MODES)}
    assert modes == {"auto": "sofia_arm.autocal_cli:register_auto"}
    r = sofia("calibrate", "auto", "--help")
    assert r.returncode == 0, r.stderr
    assert "--target-mm" in r.stdout and "--max-poses" in r.stdout
    cli_source = Path(cli.__file__).read_text()
    assert "sofia_arm" not in cli_source
