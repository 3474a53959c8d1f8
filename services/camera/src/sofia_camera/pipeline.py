"""One depth + colour pair -> one organized colour-frame cloud: filters, alignment, deprojection,
depth correction, stamps. No bus here (the service publishes what this returns)."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .camera_info import encode_camera_info
from .clock import ClockMap
from .cloud import FRAME_ID, CloudEncoder
from .correction import DepthCorrection
from .intrinsics import Intrinsics
from .meta import CloudMeta
from .processing import Aligner, FilterChain
from .streams import FramePair, FrameSource


@dataclass
class Output:
    """A built cloud: CDR bytes, its CameraInfo, facts, and how long it took (ms)."""

    cloud: bytearray
    camera_info: bytes
    meta: CloudMeta
    build_ms: float


class CloudPipeline:
    """Builds clouds from the pairs of one camera; ``max_skew_ms``: larger colour-depth offsets are
    not the same instant (flagged ``synced: false``)."""

    def __init__(self, filters: FilterChain, correction: DepthCorrection, max_skew_ms: float,
                 simulated: bool = False, frame_id: str = FRAME_ID) -> None:  # fmt: skip
        self.filters = filters
        self.correction = correction
        self.max_skew_ms = max_skew_ms
        self.simulated = simulated
        self.frame_id = frame_id
        self.clock = ClockMap()
        self.aligner = Aligner()
        self.encoder = CloudEncoder(frame_id)

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
        aligned = self.aligner.align(depth, pair.color)
        intr = Intrinsics.from_rs(aligned.get_profile().as_video_stream_profile().get_intrinsics())
        depth_units = np.asanyarray(aligned.get_data())
        bgra = np.asanyarray(pair.color.get_data())
        correction, source_name = self.correction.current()
        correct = None if correction is None else (lambda p: self.correction.apply(p, correction))
        cloud = self.encoder.encode(depth_units, aligned.get_units(), bgra, intr, stamp_ns, correct)
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
        return Output(cloud, encode_camera_info(intr, stamp_ns, self.frame_id), meta, build_ms)
