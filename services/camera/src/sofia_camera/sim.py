"""``--sim``: a D435 rendered from the live flange pose and injected through the software device.

``T_base_color = T_base_flange @ T_flange_cam``; the depth image is ray-cast from the left imager
(``T_base_depth = T_base_color @ T_color_depth``) with the depth stream's intrinsics, the colour
image from the colour camera: librealsense then aligns them exactly as for a real D435. Each
frame carries the pose's stamp as its bus time, so the cloud is stamped with the pose's stamp.
"""

from __future__ import annotations

import logging
import threading
import time

import numpy as np
import zenoh
from sofia_replay.synth.camera import Camera, add_sensor_effects, cast
from sofia_runtime.service import LatestSlot
from sofia_schemas.rosmsg import decode_flange_pose

from .intrinsics import Intrinsics, StreamSpec
from .sim_scene import SimWorld
from .software import SoftwareCamera

log = logging.getLogger(__name__)
POSE_FRESH_S = 1.0  # without a pose for this long the simulation says it is waiting


def synth_camera(intr: Intrinsics, noise: bool) -> Camera:
    """The ray caster's :class:`Camera` of a stream (D435 noise, dropouts, edge removal or none)."""
    extra = {} if noise else {"noise_at_half_m": 0.0, "drop_rate": 0.0}
    return Camera(
        width=intr.width, height=intr.height, fx=intr.fx, fy=intr.fy, cx=intr.ppx, cy=intr.ppy, **extra
    )  # type: ignore[arg-type]


class SimRenderer:
    """Depth (left imager) and colour images of ``world`` from a flange pose."""

    def __init__(self, world: SimWorld, spec: StreamSpec, seed: int = 0) -> None:
        self.world = world
        self.spec = spec
        self.noise = world.options.noise
        self.stereo = world.options.stereo
        self.depth_camera = synth_camera(spec.depth, self.noise)
        self.color_camera = synth_camera(spec.color, self.noise)
        self.rng = np.random.default_rng(seed)
        self._cached: tuple[bytes, np.ndarray, np.ndarray] | None = None

    def T_base_color(self, T_base_flange: np.ndarray) -> np.ndarray:
        """(4, 4) colour optical frame in the base frame (on the flange, or on a fixed mount)."""
        return self.world.T_base_color(T_base_flange)

    def clean(self, T_base_flange: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Noise-free depth (Hd, Wd) metres (inf: no hit) and colour (Hc, Wc, 3) uint8; the last
        pose's images are reused while the pose does not change."""
        self.world.refresh()  # the shared world's objects where they are now
        key = np.round(T_base_flange, 9).tobytes() + self.world.version.to_bytes(8, "little")
        if self._cached is not None and self._cached[0] == key:
            return self._cached[1], self._cached[2]
        self.world.at(T_base_flange)  # the eye-to-hand cell's ball where the flange is
        T_base_color = self.T_base_color(T_base_flange)
        depth, _, _ = cast(self.world.raycasting, T_base_color @ self.spec.T_color_depth, self.depth_camera)
        _, ids, points_base = cast(self.world.raycasting, T_base_color, self.color_camera)
        rgb = np.zeros((self.spec.color.height, self.spec.color.width, 3), np.uint8)
        hit = ids >= 0
        rgb[hit] = self.world.colour_of(ids[hit], points_base[hit])  # type: ignore[operator]
        self._cached = (key, depth, rgb)
        return depth, rgb

    def render(self, T_base_flange: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Depth (Hd, Wd) metres with NaN for no depth (with the D435 depth effects unless ``--sim-noise
        none``), colour (Hc, Wc, 3) uint8."""
        if self.stereo:
            return self.stereo_depth(T_base_flange), self.clean(T_base_flange)[1]
        depth, rgb = self.clean(T_base_flange)
        cam = self.depth_camera
        if not self.noise:
            return np.where((depth >= cam.min_depth) & (depth <= cam.max_depth), depth, np.nan), rgb
        return add_sensor_effects(depth, cam, self.rng), rgb

    def stereo_depth(self, T_base_flange: np.ndarray) -> np.ndarray:
        """Depth (Hd, Wd) of replay's active-stereo D435 model (right-imager shadows, flying pixels,
        disparity quantisation, dark-surface holes): a new noise draw, and two ray casts, per frame."""
        from sofia_replay.synth.d435 import StereoModel, cast_camera, stereo_depth

        self.world.at(T_base_flange)
        T_base_depth = self.T_base_color(T_base_flange) @ self.spec.T_color_depth
        cam = synth_camera(self.spec.depth, noise=False)
        c = cast_camera(self.world.raycasting, T_base_depth, cam)
        hit = c.ids >= 0
        albedo = np.zeros(c.depth.shape)
        albedo[hit] = self.world.colour_of(c.ids[hit], c.points_base[hit]).mean(axis=-1) / 255.0  # type: ignore[operator]
        return stereo_depth(self.world.raycasting, c, albedo, T_base_depth, cam, StereoModel(), self.rng)


class SimDriver:
    """Feeds ``camera`` with renders of the newest flange pose, at most ``fps`` times a second."""

    def __init__(self, camera: SoftwareCamera, renderer: SimRenderer, fps: float, pose_key: str) -> None:
        self.camera = camera
        self.renderer = renderer
        self.period_s = 1.0 / fps
        self.pose_key = pose_key
        self.poses: LatestSlot[tuple[int, np.ndarray]] = LatestSlot(1)
        self.last_pose_at = 0.0
        self.last_stamp_ns = 0
        self.bad_poses = 0
        self.render_ms = 0.0

    def on_pose(self, sample: zenoh.Sample) -> None:
        try:
            pose = decode_flange_pose(sample.payload.to_bytes())
        except ValueError as e:
            self.bad_poses += 1
            log.warning("flange pose on %s: %s", sample.key_expr, e)
            return
        self.last_pose_at = time.monotonic()
        self.poses.put((pose.stamp_ns, pose.matrix()))

    def idle_reason(self) -> str | None:
        if time.monotonic() - self.last_pose_at > POSE_FRESH_S:
            return f"simulated camera waiting for a flange pose on {self.pose_key}"
        return None

    def step(self, stamp_ns: int, T_base_flange: np.ndarray) -> None:
        """Render the pose and inject it (stamped ``stamp_ns``); older stamps than the last are skipped."""
        if stamp_ns <= self.last_stamp_ns:
            return
        t0 = time.perf_counter()
        depth, rgb = self.renderer.render(T_base_flange)
        self.render_ms = (time.perf_counter() - t0) * 1e3
        self.camera.inject(depth, rgb, device_time_ms=stamp_ns / 1e6, stamp_ns=stamp_ns)
        self.last_stamp_ns = stamp_ns

    def run(self, stop: threading.Event) -> None:
        next_at = time.monotonic()
        while not stop.is_set():
            item = self.poses.take(timeout=0.1)
            if item is None:
                continue
            wait = next_at - time.monotonic()
            if wait > 0:  # at most fps frames a second: a newer pose may replace this one meanwhile
                stop.wait(wait)
                item = self.poses.take(timeout=0) or item
            next_at = max(next_at + self.period_s, time.monotonic())
            self.step(*item)
