"""What ``sofia calibrate`` reads: blob samples from any file source, and the files of the other
targets (--target sphere|poses|charuco|apriltag) with their calibration."""

from __future__ import annotations

import argparse
import sys
from typing import Any

import numpy as np
from sofia_schemas.frames import CAMERA_FRAME as CHILD_FRAME
from sofia_schemas.frames import FLANGE_FRAME as PARENT_FRAME

from .errors import InputMismatch

GUESS_QUAT_TOL = 0.01  # a typed guess quaternion within 1 % of unit norm is normalised


def add_target_args(p: argparse.ArgumentParser) -> None:
    """--target / --setup and the inputs of the sphere and pose targets."""
    g = p.add_argument_group("target and set-up")
    g.add_argument("--target", default="blob", choices=("blob", "sphere", "poses", "charuco", "apriltag"),
                   help="what the camera sees: blob (default), sphere (--clouds, or a coloured ball in --mcap's clouds), poses (--pose-pairs), "
                   "charuco (--images, --camera-matrix, --board), apriltag (--images, --camera-matrix, --tag-size)")  # fmt: skip
    g.add_argument("--setup", default="eye-in-hand", choices=("eye-in-hand", "eye-to-hand"),
                   help="eye-in-hand: camera on the flange (T_flange_cam, default); eye-to-hand: camera "
                   "fixed, target on the flange (T_base_cam)")  # fmt: skip
    g.add_argument("--clouds", nargs="+", metavar="CLOUD", help="sphere: one PCD/PLY cloud per flange pose")
    g.add_argument("--cloud-unit", type=float, default=1.0, help="metres per cloud unit (default 1)")
    g.add_argument(
        "--radius", type=float, help="sphere radius, metres (default: one radius fitted to all the views)"
    )
    g.add_argument("--euler-poses", metavar="FILE",
                   help="flange poses as 'a, b, c, x, y, z' lines (radians; see --euler-convention)")  # fmt: skip
    g.add_argument("--euler-convention", default="xyz", help="SciPy Euler sequence (default xyz)")
    g.add_argument(
        "--length-unit", type=float, default=1e-3, help="metres per --euler-poses unit (default mm)"
    )
    g.add_argument("--pose-pairs", metavar="FILE",
                   help="poses: OpenCV YAML of T1_i (flange) / T2_i (target in camera) pairs")  # fmt: skip
    g.add_argument(
        "--images", nargs="+", metavar="IMAGE", help="charuco: one rectified image per flange pose"
    )
    g.add_argument("--depth", nargs="+", metavar="DEPTH",
                   help="charuco: one depth image per image (16-bit PNG, registered to it): the corners "
                   "with depth refine the fit")  # fmt: skip
    g.add_argument("--depth-unit", type=float, default=1e-3, help="metres per --depth unit (default mm)")
    g.add_argument("--camera-matrix", metavar="'fx fy cx cy'|FILE",
                   help="charuco: the images' intrinsics (pixels), or a YAML/JSON file with K or fx fy cx cy")  # fmt: skip
    g.add_argument("--board", nargs=4, type=float, metavar=("COLS", "ROWS", "SQUARE", "MARKER"),
                   help="charuco: squares across and down, square and marker sides in metres (default 7 5 0.04 0.03)")  # fmt: skip
    g.add_argument(
        "--board-dict", default="DICT_5X5_100", help="charuco: the ArUco dictionary (default DICT_5X5_100)"
    )
    g.add_argument(
        "--tag-size",
        type=float,
        default=0.08,
        help="apriltag: the black square's side, metres (default 0.08)",
    )
    g.add_argument(
        "--tag-family",
        default="DICT_APRILTAG_36h11",
        help="apriltag: OpenCV's dictionary (default DICT_APRILTAG_36h11)",
    )
    g.add_argument("--tag-id", type=int, default=0, help="apriltag: the tag's id (default 0)")


def run_target(args: argparse.Namespace) -> Any:
    """The calibration of ``--target`` / ``--setup``."""
    from .any_target import calibrate_target, frames

    parent, child = frames(args.setup)
    parent = parent if args.parent_frame == PARENT_FRAME else args.parent_frame
    child = child if args.child_frame == CHILD_FRAME else args.child_frame
    common: dict[str, Any] = {"parent_frame": parent, "child_frame": child}
    if args.target == "poses":
        from .targets.files import read_opencv_pose_pairs

        if not args.pose_pairs:
            raise InputMismatch("--target poses needs --pose-pairs FILE")
        T, T_cam_target = read_opencv_pose_pairs(args.pose_pairs)
        return calibrate_target("poses", args.setup, T_base_flange=T, T_cam_target=T_cam_target, **common)
    if args.target in ("charuco", "apriltag"):
        return calibrate_target(args.target, args.setup, **image_inputs(args), **common)
    options: dict[str, Any] = {"sigma": args.noise, "loss": args.loss, "exclude_outliers": not args.keep_outliers,
               "correction": args.correction, "depth_scale_prior": scale_prior(args), "guess": guess(args), **common}  # fmt: skip
    if args.target == "sphere" and args.mcap:  # a coloured ball in the recording's camera clouds
        from .inputs.mcap import read_mcap

        m = read_mcap(args.mcap, from_clouds=True, target="ball", radius_m=args.radius)
        for r in m.rejected:
            print(f"skipped: {r}", file=sys.stderr)
        if m.radius_m is not None:
            print(f"ball radius {1e3 * m.radius_m:.2f} mm, fitted to {len(m.p_cam)} views", file=sys.stderr)
        return calibrate_target("blob", args.setup, T_base_flange=m.T_base_flange, p_cam=m.p_cam, **options)
    if args.target == "blob":
        p_cam, T = load_samples(args)
        return calibrate_target("blob", args.setup, T_base_flange=T, p_cam=p_cam, **options)
    from .targets.files import read_cloud

    given = flange_poses(args)
    T = load_samples(args)[1] if given is None else given
    if not args.clouds:
        raise InputMismatch("--target sphere needs --clouds (one cloud file per flange pose) or --mcap FILE")
    if len(args.clouds) != len(T):
        raise InputMismatch(f"{len(args.clouds)} clouds but {len(T)} flange poses")
    clouds = [read_cloud(c) * args.cloud_unit for c in args.clouds]
    return calibrate_target(
        "sphere", args.setup, T_base_flange=T, clouds_cam=clouds, radius_m=args.radius, **options
    )


def image_inputs(args: argparse.Namespace) -> dict[str, Any]:
    """T_base_flange (--tfs or --euler-poses), the grey images, K and the board or the tag of
    --target charuco or apriltag."""
    from .targets.apriltag import TagSpec
    from .targets.charuco import BoardSpec
    from .targets.files import read_camera_matrix, read_grey_images

    if not args.images or not args.camera_matrix:
        raise InputMismatch(
            f"--target {args.target} needs --images (one per flange pose) and --camera-matrix"
        )
    T = flange_poses(args)
    if T is None:
        raise InputMismatch(
            f"--target {args.target} needs the flange poses: --tfs FILE or --euler-poses FILE"
        )
    if len(args.images) != len(T):
        raise InputMismatch(f"{len(args.images)} images but {len(T)} flange poses")
    inputs: dict[str, Any] = {
        "T_base_flange": T,
        "images": read_grey_images(args.images),
        "K": read_camera_matrix(args.camera_matrix),
    }
    if args.depth:
        from .targets.files import read_depth_clouds

        if args.target != "charuco":
            raise InputMismatch(
                f"--depth is for --target charuco (its corners with depth), not {args.target}"
            )
        if len(args.depth) != len(args.images):
            raise InputMismatch(f"{len(args.depth)} depth images but {len(args.images)} images")
        inputs["clouds_cam"] = read_depth_clouds(args.depth, inputs["K"], args.depth_unit)
    if args.target == "apriltag":
        return {**inputs, "tag": TagSpec(args.tag_family, args.tag_id, args.tag_size)}
    import cv2

    if not args.board_dict.startswith("DICT_") or not hasattr(cv2.aruco, args.board_dict):
        raise InputMismatch(
            f"--board-dict {args.board_dict!r} is not an OpenCV ArUco dictionary (e.g. DICT_5X5_100)"
        )
    board = BoardSpec(dictionary=args.board_dict) if args.board is None else BoardSpec(
        (int(args.board[0]), int(args.board[1])), args.board[2], args.board[3], args.board_dict
    )  # fmt: skip
    return {**inputs, "board": board}


def flange_poses(args: argparse.Namespace) -> np.ndarray | None:
    """(n, 4, 4) T_base_flange of --euler-poses or --tfs, None when neither is given."""
    from .inputs.lab import read_tfs
    from .targets.files import read_euler_poses

    if args.euler_poses:
        return read_euler_poses(args.euler_poses, args.euler_convention, args.length_unit)
    return read_tfs(args.tfs) if args.tfs else None


def load_samples(args: argparse.Namespace) -> tuple[np.ndarray, np.ndarray]:
    """(p_cam, T_base_flange) from whichever source the arguments name."""
    from .inputs.lab import read_lab, read_poses
    from .inputs.sample_files import read_joints, read_samples

    if args.mcap:
        from .inputs.mcap import read_mcap

        m = read_mcap(args.mcap, from_clouds=args.from_clouds)
        for r in m.rejected:
            print(f"skipped: {r}", file=sys.stderr)
        return m.p_cam, m.T_base_flange
    if args.samples:
        return read_samples(args.samples)
    if args.poses and args.tfs:
        return read_lab(args.poses, args.tfs)
    if args.poses and args.joints:
        p_cam, T = read_poses(args.poses), read_joints(args.joints)
        if len(p_cam) != len(T):
            raise InputMismatch(
                f"{args.poses} has {len(p_cam)} blob positions but {args.joints} has {len(T)} joint rows"
            )
        return p_cam, T
    raise InputMismatch("give --poses with --tfs or --joints, or --samples FILE, or --mcap FILE")


def guess(args: argparse.Namespace) -> np.ndarray | None:
    """The (4, 4) transform of ``--guess`` (x y z qx qy qz qw), or None; a quaternion typed within
    ``GUESS_QUAT_TOL`` of unit norm is normalised."""
    if not args.guess:
        return None
    from sofia_schemas.transforms import make_transform

    g = np.array(args.guess)
    norm = float(np.linalg.norm(g[3:]))
    if abs(norm - 1.0) < GUESS_QUAT_TOL:  # hand-typed: normalise small rounding errors
        g[3:] /= norm
    return make_transform(g[:3], g[3:])


def scale_prior(args: argparse.Namespace) -> Any:
    """The ScalePrior of ``--scale-prior`` (an earlier result file), or None."""
    from .result_files import read_scale_prior

    return None if args.scale_prior is None else read_scale_prior(args.scale_prior)
