"""Fixtures of the command-line tests: the docs walks' folder, laid out as after `make demo`
(synthetic recordings in `var/recordings/`, the lab's files in `data/lab/`) with the files the
docs name as example inputs (`perception.bag`, `recording.mcap`, `data/scenes.mcap`,
`cloud.pcd`, `scan.ply`, `points.npy`, `camera.mcap`, `T_flange_cam.yaml`, `poses.txt`, `tfs.txt`,
`q.txt`, `s.csv`, `s.json`, `rec.mcap`) made from the same synthetic data."""

from __future__ import annotations

import json
import logging
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import open3d as o3d
import pytest
import yaml
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore
from scipy.spatial.transform import Rotation
from sofia_calibrator.fitting.simulate import make_problem
from sofia_replay import iter_messages, read_truth
from sofia_schemas import pointcloud
from sofia_schemas.kinematics import panda_fk
from sofia_system.launcher import sofia_executable

ROOT = Path(__file__).parents[2]
PC2 = "sensor_msgs/msg/PointCloud2"
TS = "geometry_msgs/msg/TransformStamped"


@pytest.fixture
def root_logging() -> Iterator[None]:
    """`sofia` configures the root logger; put this process's logging back afterwards."""
    root = logging.getLogger()
    handlers, level = list(root.handlers), root.level
    yield
    root.handlers[:] = handlers
    root.setLevel(level)


def run_sofia(cwd: Path, *argv: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    """``sofia ARGV`` run to its end in ``cwd``, its output captured."""
    return subprocess.run(
        [*sofia_executable(), *argv], cwd=cwd, capture_output=True, text=True, timeout=timeout
    )


_ran: dict[tuple[Path, tuple[str, ...]], subprocess.CompletedProcess[str]] = {}


def run_once(cwd: Path, *argv: str) -> subprocess.CompletedProcess[str]:
    """``sofia ARGV`` in ``cwd`` as :func:`run_sofia`, once per run: a command that several pages (or
    both docs walks) give again gets the first run's result."""
    key = (cwd, argv)
    if key not in _ran:
        _ran[key] = run_sofia(cwd, *argv)
    return _ran[key]


def _bag(path: Path, scenes: Path) -> None:
    """A ROS 1 bag like the lab's perception.bag: base-frame clouds on /pc_glob, a /tool_pose."""
    ros1, ros2 = get_typestore(Stores.ROS1_NOETIC), get_typestore(Stores.ROS2_HUMBLE)
    T = ros1.types
    with Writer(path) as w:
        pc = w.add_connection("/pc_glob", PC2, typestore=ros1)
        tool = w.add_connection("/tool_pose", TS, typestore=ros1)
        for i, m in enumerate(x for x in iter_messages(scenes) if x.topic == "/pc_glob"):
            c: Any = ros2.deserialize_cdr(m.data, PC2)
            header = T["std_msgs/msg/Header"](seq=i, stamp=c.header.stamp, frame_id=c.header.frame_id)
            fields = [T["sensor_msgs/msg/PointField"](name=f.name, offset=f.offset, datatype=f.datatype,
                                                      count=f.count) for f in c.fields]  # fmt: skip
            cloud = T[PC2](header=header, height=c.height, width=c.width, fields=fields, is_bigendian=False,
                           point_step=c.point_step, row_step=c.row_step, data=c.data, is_dense=c.is_dense)  # fmt: skip
            w.write(pc, m.log_time_ns, ros1.serialize_ros1(cloud, PC2))
            pose = T[TS](header=header, child_frame_id="panda_link8", transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=0.4, y=0.0, z=0.5),
                rotation=T["geometry_msgs/msg/Quaternion"](x=1.0, y=0.0, z=0.0, w=0.0)))  # fmt: skip
            w.write(tool, m.log_time_ns + 1, ros1.serialize_ros1(pose, TS))


def _cloud_files(cwd: Path, scenes: Path) -> None:
    """cloud.pcd, scan.ply and points.npy: the first base-frame cloud of ``scenes`` (organized)."""
    msg = next(m for m in iter_messages(scenes) if m.topic == "/pc_glob")
    xyz = pointcloud.decode(msg.data).xyz().astype(np.float32)  # (H, W, 3) base frame
    np.save(cwd / "points.npy", xyz)
    h, w = xyz.shape[:2]
    header = f"VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {w}\nHEIGHT {h}\n"
    header += f"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {h * w}\nDATA ascii\n"
    rows = "\n".join(" ".join(f"{v:.6g}" for v in p) for p in xyz.reshape(-1, 3))
    (cwd / "cloud.pcd").write_text(header + rows + "\n")
    finite = xyz.reshape(-1, 3)[np.isfinite(xyz.reshape(-1, 3)).all(axis=1)]
    o3d.io.write_point_cloud(cwd / "scan.ply", o3d.geometry.PointCloud(o3d.utility.Vector3dVector(finite)))


def _calibration_files(cwd: Path) -> None:
    """poses.txt + tfs.txt (flange poses, the lab's format) or q.txt (Panda joints), s.csv and s.json:
    one blob seen from 10 joint configurations."""
    rng = np.random.default_rng(0)
    q = np.array([0.0, -0.5, 0.0, -2.2, 0.0, 1.9, 0.8]) + rng.uniform(-0.35, 0.35, (10, 7))
    T_base_cam = panda_fk(q) @ make_problem(3, rng).T_flange_cam
    p_base = T_base_cam[0, :3, 3] + 0.4 * T_base_cam[0, :3, 2]
    p_cam = np.einsum("nji,nj->ni", T_base_cam[:, :3, :3], p_base - T_base_cam[:, :3, 3])
    (cwd / "q.txt").write_text("\n".join(" ".join(f"{v:.17g}" for v in r) for r in q) + "\n")
    (cwd / "poses.txt").write_text("\n".join(",".join(f"{v:.17g}" for v in r) for r in p_cam) + "\n")
    T_base_flange = panda_fk(q)
    quats_xyzw = Rotation.from_matrix(T_base_flange[:, :3, :3]).as_quat()
    blocks = [f"translation: \nx: {t[0]!r}\ny: {t[1]!r}\nz: {t[2]!r}\nrotation: \n"
              + "".join(f"{a}: {v!r}\n" for a, v in zip("xyzw", quat, strict=True))
              for t, quat in zip(T_base_flange[:, :3, 3].tolist(), quats_xyzw.tolist(), strict=True)]  # fmt: skip
    (cwd / "tfs.txt").write_text("".join(blocks))
    columns = ["px", "py", "pz", *(f"q{i}" for i in range(1, 8))]
    rows = [",".join(f"{v:.17g}" for v in (*p, *j)) for p, j in zip(p_cam, q, strict=True)]
    (cwd / "s.csv").write_text(",".join(columns) + "\n" + "\n".join(rows) + "\n")
    samples = [{"p_cam": p.tolist(), "q": j.tolist()} for p, j in zip(p_cam, q, strict=True)]
    (cwd / "s.json").write_text(json.dumps(samples))


@pytest.fixture(scope="session")
def walk_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder laid out as after `make demo`, with the docs' example inputs."""
    cwd = tmp_path_factory.mktemp("readme")
    shutil.copytree(ROOT / "data" / "lab", cwd / "data" / "lab")
    shutil.copytree(ROOT / "config", cwd / "config")
    rec = cwd / "var" / "recordings"
    for argv in (("synth", "scenes", str(rec / "scenes.mcap"), "--kind", "mixed", "-n", "6"),
                 ("synth", "calibration", str(rec / "calibration.mcap"), "--n-poses", "10")):  # fmt: skip
        r = run_sofia(cwd, *argv)
        assert r.returncode == 0, r.stderr
    scenes = rec / "scenes.mcap"
    for name in ("recording.mcap", "camera.mcap"):
        shutil.copy(scenes, cwd / name)
    shutil.copy(rec / "calibration.mcap", cwd / "rec.mcap")
    shutil.copy(scenes, cwd / "data" / "scenes.mcap")
    truth = read_truth(scenes)
    assert truth is not None
    (cwd / "T_flange_cam.yaml").write_text(
        yaml.safe_dump({"matrix": np.asarray(truth["T_flange_cam"]).tolist()})
    )
    _bag(cwd / "perception.bag", scenes)
    _cloud_files(cwd, scenes)
    _calibration_files(cwd)
    (cwd / "recordings").mkdir()
    return cwd
