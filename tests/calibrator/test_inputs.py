"""Readers: the lab's poses.txt + tfs.txt, CSV, JSON, Panda joints (forward kinematics), MCAP."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from sofia_calibrator import ParseError, calibrate, read_lab, read_poses, read_tfs
from sofia_calibrator.errors import InputMismatch
from sofia_calibrator.fitting.simulate import make_problem
from sofia_calibrator.inputs.sample_files import read_csv, read_joints, read_json, read_samples
from sofia_schemas.kinematics import KinematicsError, panda_fk
from sofia_schemas.transforms import as_transforms, matrix_to_quat_xyzw

TFS_BLOCK = "translation: \nx: 0.1\ny: 0.2\nz: 0.3\nrotation: \nx: 0.0\ny: 0.0\nz: 0.0\nw: 1.0\n"


def test_lab_files_parse(lab_dir: Path) -> None:
    p, T = read_lab(lab_dir / "poses.txt", lab_dir / "tfs.txt")
    assert p.shape == (11, 3) and T.shape == (11, 4, 4)
    as_transforms(T)
    np.testing.assert_allclose(p[0], [-0.034076131880283356, -0.20666153728961945, 0.6158857345581055])
    np.testing.assert_allclose(T[0, :3, 3], [0.24309599778978433, -0.1065663025106727, 0.9711693922297671])


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("0.1,0.2\n", r"poses.txt:1: expected 3 comma-separated values"),
        ("0.1,0.2,abc\n", r"poses.txt:1: blob z 'abc' is not a number"),
        ("0.1,0.2,nan\n", r"poses.txt:1: blob z is nan"),
        ("", "no samples"),
    ],
)
def test_poses_errors(tmp_path: Path, text: str, match: str) -> None:
    (tmp_path / "poses.txt").write_text(text)
    with pytest.raises(ParseError, match=match):
        read_poses(tmp_path / "poses.txt")


@pytest.mark.parametrize(
    ("text", "match"),
    [
        (TFS_BLOCK.replace("w: 1.0", "w: 2.0"), "norm 2.00"),  # unnormalised quaternion
        (TFS_BLOCK.replace("w: 1.0\n", ""), r"rotation needs \['x', 'y', 'z', 'w'\]"),
        (TFS_BLOCK.replace("y: 0.2", "y: oops"), r"tfs.txt:3: translation y 'oops' is not a number"),
        (TFS_BLOCK.replace("x: 0.1", "speed 3"), r"tfs.txt:2: expected 'translation:'"),
        (TFS_BLOCK.replace("z: 0.3", "w: 0.3"), "translation has no 'w'"),
    ],
)
def test_tfs_errors(tmp_path: Path, text: str, match: str) -> None:
    (tmp_path / "tfs.txt").write_text(text)
    with pytest.raises(ParseError, match=match):
        read_tfs(tmp_path / "tfs.txt")


def test_mismatched_counts(tmp_path: Path) -> None:
    (tmp_path / "poses.txt").write_text("0.1,0.2,0.5\n0.1,0.2,0.5\n")
    (tmp_path / "tfs.txt").write_text(TFS_BLOCK)
    with pytest.raises(InputMismatch, match=r"2 blob positions but .* has 1 flange poses"):
        read_lab(tmp_path / "poses.txt", tmp_path / "tfs.txt")


def _write_problem_csv(path: Path, p: np.ndarray, T: np.ndarray) -> None:
    q = matrix_to_quat_xyzw(T[:, :3, :3])
    rows = ["px,py,pz,tx,ty,tz,qx,qy,qz,qw"]
    rows += [",".join(f"{v:.17g}" for v in [*p[i], *T[i, :3, 3], *q[i]]) for i in range(len(p))]
    path.write_text("\n".join(rows) + "\n")


def test_csv_and_json_round_trip(tmp_path: Path) -> None:
    pr = make_problem(7, np.random.default_rng(3))
    _write_problem_csv(tmp_path / "s.csv", pr.p_cam, pr.T_base_flange)
    p, T = read_samples(tmp_path / "s.csv")
    np.testing.assert_allclose(p, pr.p_cam)
    np.testing.assert_allclose(T, pr.T_base_flange, atol=1e-12)
    q = matrix_to_quat_xyzw(pr.T_base_flange[:, :3, :3])
    items = [{"p_cam": list(pr.p_cam[i]), "translation": list(pr.T_base_flange[i, :3, 3]),
              "rotation_xyzw": list(q[i])} for i in range(7)]  # fmt: skip
    (tmp_path / "s.json").write_text(json.dumps({"samples": items}))
    p2, T2 = read_json(tmp_path / "s.json")
    np.testing.assert_allclose(T2, pr.T_base_flange, atol=1e-12)
    np.testing.assert_allclose(p2, pr.p_cam)


def test_csv_and_json_errors(tmp_path: Path) -> None:
    (tmp_path / "a.csv").write_text("px,py,pz,tx\n1,2,3,4\n")
    with pytest.raises(ParseError, match="must name"):
        read_csv(tmp_path / "a.csv")
    (tmp_path / "b.json").write_text(
        '[{"p_cam": [0, 0, 1], "translation": [0, 0, 0], "rotation_xyzw": [0, 0, 0, 3]}]'
    )
    with pytest.raises(ParseError, match=r"norm 3\.0"):
        read_json(tmp_path / "b.json")
    (tmp_path / "c.json").write_text("[{")
    with pytest.raises(ParseError, match="invalid JSON"):
        read_json(tmp_path / "c.json")
    (tmp_path / "d.json").write_text('[{"p_cam": [0, 0]}]')
    with pytest.raises(ParseError, match="p_cam must be 3 numbers"):
        read_json(tmp_path / "d.json")
    with pytest.raises(ParseError, match="unknown sample file type"):
        read_samples(tmp_path / "x.txt")


def test_panda_fk_ready_pose() -> None:
    """libfranka's ready pose puts the flange 0.307 m forward, 0.590 m up, pointing down."""
    T = panda_fk(np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4]))
    np.testing.assert_allclose(T[:3, 3], [0.3069, 0.0, 0.5903], atol=5e-4)
    np.testing.assert_allclose(T[:3, 2], [0.0, 0.0, -1.0], atol=1e-9)
    as_transforms(T)


def test_panda_fk_errors() -> None:
    with pytest.raises(KinematicsError, match=r"shape \(n, 7\)"):
        panda_fk(np.zeros(6))
    with pytest.raises(KinematicsError, match=r"joint 4 of sample 0 is 0\.0000 rad, outside"):
        panda_fk(np.zeros(7))
    with pytest.raises(KinematicsError, match="non-finite"):
        panda_fk(np.full(7, np.nan))


def test_joints_file_drives_a_calibration(tmp_path: Path) -> None:
    """Joint positions through forward kinematics give flange poses the calibrator can use."""
    rng = np.random.default_rng(0)
    q0 = np.array([0.0, -0.5, 0.0, -2.2, 0.0, 1.9, 0.8])
    q = q0 + rng.uniform(-0.35, 0.35, (10, 7))
    T_base_flange = panda_fk(q)
    T_fc = make_problem(3, rng).T_flange_cam
    T_base_cam = T_base_flange @ T_fc
    p_base = T_base_cam[0, :3, 3] + 0.4 * T_base_cam[0, :3, 2]  # a point in front of camera 0
    p_cam = np.einsum("nji,nj->ni", T_base_cam[:, :3, :3], p_base - T_base_cam[:, :3, 3])
    (tmp_path / "joints.txt").write_text("\n".join(" ".join(f"{v:.17g}" for v in r) for r in q) + "\n")
    T = read_joints(tmp_path / "joints.txt")
    np.testing.assert_allclose(T, T_base_flange)
    assert np.all(p_cam[:, 2] > 0)
    cal = calibrate(p_cam, T)
    np.testing.assert_allclose(cal.T_flange_cam, T_fc, atol=1e-6)
    (tmp_path / "bad.txt").write_text("1 2 3\n")
    with pytest.raises(ParseError, match=r"bad\.txt:1: expected 7 comma-separated values q1\.\.q7, got 3"):
        read_joints(tmp_path / "bad.txt")


def test_mcap_samples_recover_the_truth(tmp_path: Path) -> None:
    from sofia_calibrator.inputs.mcap import read_mcap
    from sofia_replay.synth.record import write_calibration_session

    session = write_calibration_session(tmp_path / "c.mcap", n_poses=8, seed=4, clouds=False)
    m = read_mcap(tmp_path / "c.mcap")
    assert len(m.p_cam) == 8 and m.rejected == []
    cal = calibrate(m.p_cam, m.T_base_flange)
    assert np.linalg.norm(cal.translation - session.T_flange_cam[:3, 3]) < 0.005
    with pytest.raises(ValueError, match="not a readable MCAP"):
        (tmp_path / "x.mcap").write_bytes(b"nope")
        read_mcap(tmp_path / "x.mcap")
