"""Depth of known geometry injected through librealsense's software device comes out as the right
points, in the colour frame, in every resolution (truth: the ray caster seen from the colour camera)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage
from sofia_camera.cloud import FRAME_ID
from sofia_camera.sim import synth_camera
from sofia_replay.synth.camera import cast
from sofia_schemas import pointcloud
from sofia_schemas.transforms import apply, invert

from .conftest import flange_above


def truth_in_color(rig, T_base_flange: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
    """Noise-free (H, W, 3) points seen by the colour camera (NaN: no hit) and a mask of pixels away
    from depth discontinuities (where a depth pixel of one surface may cover a colour pixel of another)."""
    T_base_color = rig.renderer.T_base_color(T_base_flange)
    cam = synth_camera(rig.spec.color, noise=False)
    depth, _, _ = cast(rig.renderer.world.raycasting, T_base_color, cam)
    points = cam.ray_directions_cam() * np.where(np.isfinite(depth), depth, np.nan)[..., None]
    finite = np.where(np.isfinite(depth), depth, 10.0)
    jump = ndimage.maximum_filter(finite, size=7) - ndimage.minimum_filter(finite, size=7)
    return points, jump < 0.01


def one_cloud(rig, T_base_flange: np.ndarray, t_ms: float = 1000.0):  # type: ignore[no-untyped-def]
    depth, rgb = rig.renderer.render(T_base_flange)
    rig.camera.inject(depth, rgb, t_ms)
    pair = rig.camera.wait_pair(2.0)
    assert pair is not None, "the software device delivered no frame"
    stamp, color_stamp = rig.pipeline.stamp(pair, rig.camera)
    return rig.pipeline.build(pair, rig.camera, stamp, color_stamp)


@pytest.mark.parametrize("align", ["registration", "librealsense"])
@pytest.mark.parametrize("width,height", [(640, 480), (848, 480), (1280, 720)])
def test_points_match_the_rendered_geometry(
    make_rig, board_world, width: int, height: int, align: str
) -> None:  # type: ignore[no-untyped-def]
    rig = make_rig(board_world, width, height)
    rig.pipeline.align = align
    T_base_flange = flange_above(board_world)
    out = one_cloud(rig, T_base_flange)
    cloud = pointcloud.decode(out.cloud)
    assert (cloud.frame_id, cloud.height, cloud.width) == (FRAME_ID, height, width)
    assert cloud.field_names() == ["x", "y", "z", "rgb"] and cloud.point_step == 16
    xyz = cloud.xyz().astype(np.float64)
    truth, smooth = truth_in_color(rig, T_base_flange)
    both = np.isfinite(xyz[..., 2]) & np.isfinite(truth[..., 2]) & smooth
    assert both.mean() > 0.9, f"only {both.mean():.1%} of the pixels have depth"
    err_mm = np.linalg.norm(xyz[both] - truth[both], axis=-1) * 1e3
    p50, p99 = np.percentile(err_mm, [50, 99])
    assert p50 < 0.5 and p99 < 1.0, (
        f"{width}x{height} {align}: point error p50 {p50:.2f} mm, p99 {p99:.2f} mm"
    )
    # no depth where the colour camera sees nothing (beyond the table)
    assert not np.isfinite(xyz[~np.isfinite(truth[..., 2])][..., 2]).any()


def test_colour_is_aligned_with_depth(make_rig, board_world) -> None:  # type: ignore[no-untyped-def]
    """Pixels coloured as the object carry points on the object: depth was moved into the colour
    camera's view (15 mm beside the depth imager), not laid over the colour image as is."""
    rig = make_rig(board_world)
    T_base_flange = flange_above(board_world, height=0.35)
    cloud = pointcloud.decode(one_cloud(rig, T_base_flange).cloud)
    obj = board_world.truth()["objects"][0]
    colour = np.array(board_world.scene.objects[0].colour)  # type: ignore[union-attr]
    on_object = (cloud.rgb() == colour).all(axis=-1) & np.isfinite(cloud.xyz()[..., 2])
    assert on_object.sum() > 500
    T_base_color = rig.renderer.T_base_color(T_base_flange)
    p_obj = apply(
        invert(np.array(obj["T_base_obj"])), apply(T_base_color, cloud.xyz()[on_object].astype(float))
    )
    inside = (np.abs(p_obj) <= np.array(obj["extents"]) / 2 + 0.002).all(axis=-1)
    assert inside.mean() > 0.97, f"only {inside.mean():.1%} of the object's colour pixels have points on it"


def test_camera_info_matches_the_cloud(make_rig, board_world) -> None:  # type: ignore[no-untyped-def]
    from sofia_camera.camera_info import decode_camera_info

    rig = make_rig(board_world, 848, 480)
    out = one_cloud(rig, flange_above(board_world))
    info = decode_camera_info(out.camera_info)
    cloud = pointcloud.decode(out.cloud)
    assert (info.width, info.height, info.header.frame_id) == (848, 480, FRAME_ID)
    assert info.header.stamp.sec * 1_000_000_000 + info.header.stamp.nanosec == cloud.stamp_ns
    np.testing.assert_allclose(info.k.reshape(3, 3), rig.spec.color.K)


def test_rays_equal_librealsense_deprojection() -> None:
    import pyrealsense2 as rs
    from sofia_camera.intrinsics import Intrinsics

    for model in ("none", "brown_conrady", "inverse_brown_conrady"):
        intr = Intrinsics(640, 480, 612.3, 611.9, 321.4, 238.7, model, (0.02, -0.01, 0.0005, -0.0003, 0.001))
        rays = intr.rays()
        for u, v in ((0, 0), (639, 479), (100, 400), (320, 240)):
            p = rs.rs2_deproject_pixel_to_point(intr.to_rs(), [float(u), float(v)], 1.0)
            np.testing.assert_allclose(rays[v, u], p[:2], atol=2e-5, err_msg=f"{model} pixel {(u, v)}")


def test_active_stereo_model_through_the_device(make_rig) -> None:  # type: ignore[no-untyped-def]
    """``--sim-noise stereo``: replay's active-stereo model (shadows beside raised objects, disparity
    steps) still comes out of librealsense as points near the truth, with fewer pixels of depth."""
    from sofia_camera.sim_scene import SimOptions, SimWorld

    world = SimWorld(SimOptions(scene="board", seed=3, stereo=True))
    rig = make_rig(world)
    T_base_flange = flange_above(world)
    xyz = pointcloud.decode(one_cloud(rig, T_base_flange).cloud).xyz().astype(np.float64)
    truth, smooth = truth_in_color(rig, T_base_flange)
    valid = np.isfinite(xyz[..., 2])
    # alignment spreads each depth pixel over ~1.6 colour pixels, so only the shadows stay as holes
    assert 0.9 < valid.mean() < np.isfinite(truth[..., 2]).mean(), f"{valid.mean():.1%} with depth"
    both = valid & np.isfinite(truth[..., 2]) & smooth
    err_mm = np.abs(xyz[both, 2] - truth[both, 2]) * 1e3
    assert np.median(err_mm) < 2.0, f"median depth error {np.median(err_mm):.2f} mm"
