"""One depth + colour pair -> one organized colour-frame cloud: filters, alignment, deprojection,
depth correction, stamps. No bus here (the service publishes what this returns)."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from sofia_schemas.frames import CAMERA_FRAME

from .camera_info import encode_camera_info
from .clock import ClockMap
from .cloud import FRAME_ID, CloudEncoder
from .correction import DepthCorrection
from .errors import BadOption
from .intrinsics import Intrinsics
from .meta import CloudMeta
from .processing import Aligner, FilterChain
from .registration import DepthRegistration
from .shm import CloudBuffers
from .streams import FramePair, FrameSource


@dataclass
class Output:
    """A built cloud: CDR bytes (a ``bytearray``, or the Zenoh shared-memory buffer they were written
    into), its CameraInfo, facts, how long it took (ms), and the cloud's attachment (the facts, and
    where a shared-memory cloud lies: :mod:`sofia_runtime.shm`)."""

    cloud: bytearray | Any
    camera_info: bytes
    meta: CloudMeta
    build_ms: float
    attachment: bytes | None = None


ALIGN_MODES = ("registration", "librealsense")


class CloudPipeline:
    """Builds clouds from the pairs of one camera; ``max_skew_ms``: larger colour-depth offsets are
    not the same instant (flagged ``synced: false``).

    align: how depth is put on the colour grid: ``registration`` (:class:`DepthRegistration`, the
    default; colour lens models it cannot project fall back to librealsense) or ``librealsense``
    (``rs.align``). buffers: where clouds are written (Zenoh shared memory, see
    :class:`~sofia_camera.shm.CloudBuffers`); None: a ``bytearray`` each.
    """

    def __init__(self, filters: FilterChain, correction: DepthCorrection, max_skew_ms: float,
                 simulated: bool = False, frame_id: str = FRAME_ID, align: str = "registration",
                 buffers: CloudBuffers | None = None) -> None:  # fmt: skip
        if align not in ALIGN_MODES:
            raise BadOption("--align", align, f"use one of {list(ALIGN_MODES)}")
        self.filters = filters
        self.correction = correction
        self.max_skew_ms = max_skew_ms
        self.simulated = simulated
        self.frame_id = frame_id
        self.clock = ClockMap()
        self.align = align
        self.aligner = Aligner()
        self.registration = DepthRegistration()
        self.encoder = CloudEncoder(frame_id)
        self.buffers = buffers

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) the registration and the cloud writer on a tiny frame,
        so that the first real frame does not wait for it."""
        warm_kernels(self.frame_id)

    def stamp(self, pair: FramePair, source: FrameSource) -> tuple[int, int | None]:
        """Bus stamps of the depth frame and of the colour frame."""
        exact = source.bus_stamp_ns(pair.depth)
        if exact is not None:
            color = None if pair.color is None else exact + round(pair.skew_ms * 1e6)
            return exact, color
        depth_ns = self.clock.stamp(pair.depth, pair.arrival_ns)
        return depth_ns, None if pair.color is None else depth_ns + round(pair.skew_ms * 1e6)

    def build(self, pair: FramePair, source: FrameSource, stamp_ns: int, color_ns: int | None) -> Output:
        """The cloud of ``pair`` (which must have a colour frame: the cloud is in its frame)."""
        assert pair.color is not None
        t0 = time.perf_counter()
        depth = self.filters.process(pair.depth)
        intr = Intrinsics.from_rs(pair.color.get_profile().as_video_stream_profile().get_intrinsics())
        if self.align == "registration" and DepthRegistration.supports(intr):
            z_m, intr = self.registration.register(depth, pair.color)
        else:
            aligned = self.aligner.align(depth, pair.color)
            z_m = self.encoder.metres(np.asanyarray(aligned.get_data()), aligned.get_units())
        bgra = np.asanyarray(pair.color.get_data())
        correction, source_name = self.correction.current()
        correct = None if correction is None else (lambda p: self.correction.apply(p, correction))
        cloud = self.encoder.encode(z_m, bgra, intr, stamp_ns, correct, self.buffers)
        build_ms = (time.perf_counter() - t0) * 1e3
        meta = CloudMeta(
            stamp_ns=stamp_ns, color_stamp_ns=color_ns, skew_ms=round(pair.skew_ms, 3),
            synced=abs(pair.skew_ms) <= self.max_skew_ms, frame_number=pair.depth.get_frame_number(),
            device_time_ms=pair.depth.get_timestamp(), filters=self.filters.describe(), simulated=self.simulated,
        )  # fmt: skip
        if correction is not None:
            meta = meta.model_copy(update={
                "depth_corrected": True, "correction_model": correction.model, "depth_scale": correction.depth_scale,
                "depth_offset_m": correction.depth_offset_m, "correction_source": source_name,
            })  # fmt: skip
        attachment = (
            meta.attachment() if self.buffers is None else self.buffers.attachment(cloud, meta.attachment())
        )
        return Output(cloud, encode_camera_info(intr, stamp_ns, self.frame_id), meta, build_ms, attachment)


def warm_kernels(frame_id: str = CAMERA_FRAME) -> None:
    """Compile the registration and the cloud writer on a tiny frame, or load them from numba's
    cache (``scripts/install.sh`` runs this once, so a fresh install's first camera start does not
    spend seconds compiling)."""
    tiny = Intrinsics(8, 6, 6.0, 6.0, 3.5, 2.5)
    z_m = DepthRegistration().register_arrays(np.full((6, 8), 500, np.uint16), 1e-3, tiny, tiny, np.eye(4))
    CloudEncoder(frame_id).encode(z_m, np.zeros((6, 8, 4), np.uint8), tiny, 0)
