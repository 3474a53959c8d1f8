"""The service's own depth -> colour registration: librealsense's projection, exact geometry under a
rotated and shifted colour camera, the z-buffer, no short-depth bias, agreement with ``rs.align``."""

from __future__ import annotations

import numpy as np
import pyrealsense2 as rs
import pytest
from scipy.spatial.transform import Rotation
from sofia_camera.errors import BadOption
from sofia_camera.intrinsics import Intrinsics
from sofia_camera.pipeline import CloudPipeline
from sofia_camera.processing import FilterChain
from sofia_camera.registration import DepthRegistration, _to_pixel, extrinsics_matrix
from sofia_schemas import pointcloud

from .conftest import BOARD_SEED, flange_above
from .test_geometry import one_cloud, truth_in_color

COEFFS = (0.08, -0.12, 0.0011, -0.0007, 0.03)


@pytest.mark.parametrize(
    "model", ["none", "brown_conrady", "inverse_brown_conrady", "modified_brown_conrady"]
)
def test_projection_equals_librealsense(model: str) -> None:
    color = Intrinsics(848, 480, 612.3, 611.9, 421.4, 238.7, model, COEFFS)
    cam = np.array([color.fx, color.fy, color.ppx, color.ppy], np.float32)
    k = np.array([1 if model != "brown_conrady" else 2, *COEFFS], np.float32) if model != "none" else None
    t = np.array([0.01, -0.02, 0.005], np.float32)
    rng = np.random.default_rng(1)
    for _ in range(20):
        a = np.array([*rng.uniform(-0.6, 0.6, 2), 1.0], np.float32)
        z = np.float32(rng.uniform(0.2, 2.0))
        u, v = _to_pixel(z, a[0], a[1], a[2], t, cam, k)
        expected = rs.rs2_project_point_to_pixel(color.to_rs(), [float(c) for c in z * a + t])
        np.testing.assert_allclose([u, v], expected, atol=2e-3, err_msg=f"{model}: point {z * a + t}")


def test_extrinsics_matrix_transforms_as_librealsense() -> None:
    ex = rs.extrinsics()
    R = Rotation.from_euler("xyz", [5.0, -8.0, 12.0], degrees=True).as_matrix()
    ex.rotation = [float(v) for v in R.T.ravel()]  # column-major, as librealsense stores it
    ex.translation = [0.015, -0.002, 0.003]
    T = extrinsics_matrix(ex)
    p = [0.1, -0.2, 0.7]
    np.testing.assert_allclose(T[:3, :3] @ p + T[:3, 3], rs.rs2_transform_point_to_point(ex, p), atol=1e-6)


def plane_depth(depth: Intrinsics, n_depth: np.ndarray, d: float) -> np.ndarray:
    """(H, W) depth of the plane ``n . p_depth = d`` seen by the depth camera, metres."""
    rays = np.concatenate([depth.rays().astype(np.float64), np.ones((depth.height, depth.width, 1))], axis=-1)
    return d / (rays @ n_depth)


def test_tilted_plane_under_rotated_shifted_colour_camera() -> None:
    """A tilted plane, a colour camera rotated by a few degrees, shifted in x, y and z, of another size
    and focal length: every colour pixel that sees the plane inside the depth camera's view gets z in
    the colour frame (not the depth frame's z, as ``rs.align`` keeps), unbiased, within the spread of
    one depth pixel."""
    depth = Intrinsics(640, 480, 383.0, 383.0, 319.5, 239.5)
    color = Intrinsics(848, 480, 610.0, 610.0, 423.5, 239.5)
    T_color_depth = np.eye(4)
    T_color_depth[:3, :3] = Rotation.from_euler("xyz", [2.0, -3.0, 1.0], degrees=True).as_matrix()
    T_color_depth[:3, 3] = [0.015, 0.004, 0.003]
    n_depth = np.array([0.25, -0.3, 1.0])
    n_depth /= np.linalg.norm(n_depth)
    d = 0.5
    units = 1e-4
    z_depth = plane_depth(depth, n_depth, d)
    z_color = DepthRegistration().register_arrays(
        np.round(z_depth / units).astype(np.uint16), units, depth, color, T_color_depth
    )
    # the plane in the colour frame: n_c . p_c = d_c; a colour pixel's ray (x_n, y_n, 1) meets it at z
    R, t = T_color_depth[:3, :3], T_color_depth[:3, 3]
    n_color = R @ n_depth
    d_color = d + n_color @ t
    rays = np.concatenate([color.rays().astype(np.float64), np.ones((color.height, color.width, 1))], axis=-1)
    z_true = d_color / (rays @ n_color)
    # colour pixels inside the depth camera's view, away from its border
    p_depth = (rays * z_true[..., None] - t) @ R  # R^T (p_c - t)
    uv = p_depth[..., :2] / p_depth[..., 2:] * depth.fx + [depth.ppx, depth.ppy]
    inside = (
        (uv[..., 0] > 2) & (uv[..., 0] < depth.width - 3) & (uv[..., 1] > 2) & (uv[..., 1] < depth.height - 3)
    )
    assert inside.mean() > 0.5
    assert np.isfinite(z_color[inside]).all(), f"{(~np.isfinite(z_color[inside])).sum()} holes on the plane"
    err_mm = (z_color[inside] - z_true[inside]) * 1e3
    assert abs(err_mm.mean()) < 0.05, f"bias {err_mm.mean():.3f} mm"
    assert np.percentile(np.abs(err_mm), 99) < 0.8, f"p99 {np.percentile(np.abs(err_mm), 99):.2f} mm"
    assert not np.isfinite(z_color[~inside & (uv[..., 0] > depth.width + 1)]).any()  # beyond the depth view


def test_nearer_surface_wins() -> None:
    """A box 10 cm in front of a wall: where the colour camera sees the box, it gets the box's depth,
    never the wall behind it (the z-buffer), wherever the depth camera saw the box."""
    depth = Intrinsics(640, 480, 383.0, 383.0, 319.5, 239.5)
    color = Intrinsics(640, 480, 615.0, 615.0, 319.5, 239.5)
    T_color_depth = np.eye(4)
    T_color_depth[0, 3] = 0.05  # a wide baseline: the box's depth pixels land on the wall's too
    z_depth = np.full((480, 640), 0.6)
    z_depth[200:280, 250:390] = 0.5
    z_color = DepthRegistration().register_arrays(
        np.round(z_depth / 1e-3).astype(np.uint16), 1e-3, depth, color, T_color_depth
    )
    # the box's face seen by the colour camera: depth columns 250..389 shifted by fx * tx / z
    u0 = (249.5 - 319.5) / 383.0 * 615.0 + 319.5 + 615.0 * 0.05 / 0.5
    u1 = (389.5 - 319.5) / 383.0 * 615.0 + 319.5 + 615.0 * 0.05 / 0.5
    v0, v1 = (199.5 - 239.5) / 383.0 * 615.0 + 239.5, (279.5 - 239.5) / 383.0 * 615.0 + 239.5
    face = z_color[int(np.ceil(v0)) : int(np.ceil(v1)), int(np.ceil(u0)) : int(np.ceil(u1))]
    assert face.size > 10_000 and np.allclose(face, 0.5), f"box face depths {np.unique(face)}"
    # the colour camera sits 5 cm left of the depth camera: the wall just right of the box lands
    # under the box's face (and loses to it), the wall just left of it is hidden from the depth camera
    u_wall_right = (389.5 - 319.5) / 383.0 * 615.0 + 319.5 + 615.0 * 0.05 / 0.6
    u_wall_left = (249.5 - 319.5) / 383.0 * 615.0 + 319.5 + 615.0 * 0.05 / 0.6
    assert u_wall_right < u1 - 5 and u_wall_left < u0 - 5
    assert np.isinf(z_color[250, int(np.ceil(u_wall_left)) + 1 : int(np.ceil(u0)) - 1]).all()
    assert np.allclose(z_color[250, int(u1) + 5 : int(u1) + 100], 0.6)
    assert np.allclose(z_color[250, int(u_wall_left) - 100 : int(u_wall_left) - 1], 0.6)


@pytest.mark.parametrize("width,height", [(640, 480), (1280, 720)])
def test_noisy_depth_without_short_bias(make_rig, width: int, height: int) -> None:  # type: ignore[no-untyped-def]
    """On noisy depth (the D435 noise model) ``rs.align`` comes out short on average (a colour pixel
    on the border of two depth pixels' boxes takes the nearer depth); the registration does not."""
    from sofia_camera.sim_scene import SimOptions, SimWorld

    world = SimWorld(SimOptions(scene="board", seed=BOARD_SEED, noise=True))
    T_base_flange = flange_above(world)
    bias = {}
    for align in ("registration", "librealsense"):
        rig = make_rig(world, width, height)
        rig.pipeline.align = align
        xyz = pointcloud.decode(one_cloud(rig, T_base_flange).cloud).xyz().astype(np.float64)
        truth, smooth = truth_in_color(rig, T_base_flange)
        both = np.isfinite(xyz[..., 2]) & np.isfinite(truth[..., 2]) & smooth
        assert both.mean() > 0.9, f"{align}: only {both.mean():.1%} of the pixels compared"
        bias[align] = float(np.mean(xyz[both, 2] - truth[both, 2]) * 1e3)
    assert abs(bias["registration"]) < 0.15, bias
    assert abs(bias["registration"]) < abs(bias["librealsense"]) / 3, bias


def test_decimated_depth_matches_rs_align(make_rig, board_world) -> None:  # type: ignore[no-untyped-def]
    """Decimated depth (half the resolution: each depth pixel covers ~3x3 colour pixels) registers as
    ``rs.align`` aligns it."""
    T_base_flange = flange_above(board_world)
    z = {}
    for align in ("registration", "librealsense"):
        rig = make_rig(board_world, 640, 480, ("decimation",))
        rig.pipeline.align = align
        z[align] = pointcloud.decode(one_cloud(rig, T_base_flange).cloud).xyz()[..., 2].astype(np.float64)
    both = np.isfinite(z["registration"]) & np.isfinite(z["librealsense"])
    assert both.mean() > 0.9
    diff_mm = np.abs(z["registration"] - z["librealsense"])[both] * 1e3
    assert np.median(diff_mm) < 0.5 and np.mean(diff_mm < 2.0) > 0.97, np.percentile(diff_mm, [50, 97])


def test_bad_input_is_refused() -> None:
    depth = Intrinsics(640, 480, 383.0, 383.0, 319.5, 239.5)
    with pytest.raises(ValueError, match="uint16"):
        DepthRegistration().register_arrays(np.zeros((480, 640), np.float32), 1e-3, depth, depth, np.eye(4))
    with pytest.raises(ValueError, match=r"\(480, 640\)"):
        DepthRegistration().register_arrays(np.zeros((240, 320), np.uint16), 1e-3, depth, depth, np.eye(4))
    assert DepthRegistration.supports(Intrinsics(640, 480, 600.0, 600.0, 320.0, 240.0, "ftheta"))  # no coeffs
    assert not DepthRegistration.supports(Intrinsics(640, 480, 600.0, 600.0, 320.0, 240.0, "ftheta", COEFFS))
    with pytest.raises(BadOption, match="--align 'fast'"):
        CloudPipeline(FilterChain(()), None, 16.0, align="fast")  # type: ignore[arg-type]
