"""librealsense's processing blocks on a depth + colour pair: the post-processing filters and the
alignment of depth to the colour image.

Filter order is Intel's recommendation: decimation, depth -> disparity, spatial, temporal,
disparity -> depth, hole filling.
"""

from __future__ import annotations

from collections.abc import Sequence

import pyrealsense2 as rs

from .errors import BadOption

FILTERS = ("decimation", "spatial", "temporal", "hole_filling")


def parse_filters(text: str | Sequence[str] | None) -> tuple[str, ...]:
    """``"spatial,temporal"`` (or ``none``/empty) -> names in the order they run; BadOption if unknown."""
    names = [n.strip() for n in (text.split(",") if isinstance(text, str) else (text or ())) if n.strip()]
    if names in ([], ["none"]):
        return ()
    unknown = [n for n in names if n not in FILTERS]
    if unknown:
        raise BadOption(
            "--filters", ",".join(names), f"unknown {unknown}; use none or some of {list(FILTERS)}"
        )
    return tuple(n for n in FILTERS if n in names)


class FilterChain:
    """The enabled filters, applied to each depth frame (temporal state persists across frames)."""

    def __init__(self, names: Sequence[str] = ()) -> None:
        self.names = parse_filters(list(names))
        self.blocks: list[rs.filter] = []
        if "decimation" in self.names:
            self.blocks.append(rs.decimation_filter())
        if {"spatial", "temporal"} & set(self.names):
            self.blocks.append(rs.disparity_transform(True))
            if "spatial" in self.names:
                self.blocks.append(rs.spatial_filter())
            if "temporal" in self.names:
                self.blocks.append(rs.temporal_filter())
            self.blocks.append(rs.disparity_transform(False))
        if "hole_filling" in self.names:
            self.blocks.append(rs.hole_filling_filter())

    def process(self, depth: rs.frame) -> rs.frame:
        for block in self.blocks:
            depth = block.process(depth)
        return depth

    def describe(self) -> str:
        return ",".join(self.names) or "none"


class Aligner:
    """Depth aligned to colour with ``rs.align``: the result has the colour stream's size and
    intrinsics, each pixel the depth (along the colour optical axis) of what that colour pixel sees."""

    def __init__(self) -> None:
        self._pair: list[rs.frame] = []
        self._out = rs.frame_queue(1, keep_frames=True)
        self._compose = rs.processing_block(self._make_frameset)
        self._compose.start(self._out)
        self._align = rs.align(rs.stream.color)

    def _make_frameset(self, _frame: rs.frame, source: rs.frame_source) -> None:
        source.frame_ready(source.allocate_composite_frame(self._pair))

    def frameset(self, depth: rs.frame, color: rs.frame) -> rs.composite_frame:
        """A frameset of ``depth`` and ``color`` (what a pipeline would deliver)."""
        self._pair = [depth, color]
        self._compose.invoke(depth)
        return self._out.wait_for_frame(1000).as_frameset()

    def align(self, depth: rs.frame, color: rs.frame) -> rs.depth_frame:
        aligned = self._align.process(self.frameset(depth, color))
        return aligned.get_depth_frame()
