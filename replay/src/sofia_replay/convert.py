"""ROS 1 bag -> SofIA MCAP (``sofia replay convert IN.bag OUT.mcap``), without a ROS installation.

Messages are converted from ROS 1 serialization to ROS 2 CDR by ``rosbags`` (the ROS 1 header's
``seq`` is dropped; everything else keeps its bytes). Converted types: point clouds, stamped
transforms, poses and points, and ``/tf`` (``tf2_msgs/TFMessage``, also the old ``tf/tfMessage``).
Other topics are skipped with a log line. Clouds are checked with the SofIA decoder; a cloud it
rejects (e.g. big-endian) is skipped with a warning naming the reason.
"""

from __future__ import annotations

import logging
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sofia_schemas import pointcloud
from sofia_schemas.errors import PointCloudError
from sofia_schemas.rosmsg import POINT_STAMPED, POINTCLOUD2, TRANSFORM_STAMPED, typestore

from .errors import BadBagError, BadMappingError, NothingConvertedError, RecordingNotFoundError
from .mcap_io import McapWriter

log = logging.getLogger(__name__)

POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
PROGRESS_PERIOD_S = 2.0  # seconds between progress log lines
REINDEX_HINT = (
    "the bag looks truncated or was not closed: run `rosbag reindex {name}` (ROS 1), then convert again"
)

# ROS 1 type (as rosbags names it) -> ROS 2 type written to the MCAP
CONVERTED_TYPES: dict[str, str] = {
    POINTCLOUD2: POINTCLOUD2,
    TRANSFORM_STAMPED: TRANSFORM_STAMPED,
    POSE_STAMPED: POSE_STAMPED,
    POINT_STAMPED: POINT_STAMPED,
    TF_MESSAGE: TF_MESSAGE,
    "tf/msg/tfMessage": TF_MESSAGE,
}


def parse_topic_map(items: list[str] | None) -> dict[str, str]:
    """``["/in=/out", ...]`` -> ``{"/in": "/out"}``; BadMappingError names a malformed item."""
    out: dict[str, str] = {}
    for item in items or []:
        src, sep, dst = item.partition("=")
        src, dst = src.strip(), dst.strip()
        if not sep or not src or not dst:
            raise BadMappingError(item, "expected SOURCE=TARGET")
        if src in out:
            raise BadMappingError(item, f"{src!r} is mapped twice")
        out[src] = dst
    return out


@dataclass
class ConversionReport:
    """What a conversion wrote (per output topic) and what it left out."""

    written: Counter[str] = field(default_factory=Counter)
    skipped_topics: dict[str, str] = field(default_factory=dict)  # input topic -> ROS 1 type
    rejected: Counter[str] = field(default_factory=Counter)  # input topic -> messages rejected

    @property
    def n_written(self) -> int:
        return sum(self.written.values())


def convert_bag(
    src: str | Path, dst: str | Path, topic_map: dict[str, str] | None = None,
    topics: list[str] | None = None, compression: str = "zstd",
) -> ConversionReport:  # fmt: skip
    """Convert the ROS 1 bag ``src`` into the MCAP ``dst``.

    topic_map: input topic -> output topic (others keep their name).
    topics: input topics to convert (default: every topic of a converted type).
    Raises BadBagError for an unreadable bag (with the ``rosbag reindex`` hint when its index is
    damaged) and NothingConvertedError when no message converts; ``dst`` is then not left behind.
    """
    from rosbags.rosbag1 import Reader, ReaderError

    src, dst = Path(src), Path(dst)
    if not src.is_file():
        raise RecordingNotFoundError(src)
    topic_map = topic_map or {}
    ts2 = typestore()
    report = ConversionReport()
    try:
        with Reader(src) as reader, McapWriter(dst, compression=compression) as writer:
            bag_counts: Counter[str] = Counter()
            for conn in reader.connections:
                bag_counts[conn.topic] += conn.msgcount
            connections = []
            for conn in reader.connections:
                if topics is not None and conn.topic not in topics:
                    continue
                if conn.msgtype not in CONVERTED_TYPES:
                    if conn.topic not in report.skipped_topics:
                        log.info("skipping %s: type %s is not converted", conn.topic, conn.msgtype)
                    report.skipped_topics[conn.topic] = conn.msgtype
                    continue
                connections.append(conn)
            missing = set(topics or []) - {c.topic for c in reader.connections}
            if missing:
                log.warning("topics not in %s: %s", src, sorted(missing))
            # an empty selection means "every connection" to rosbags
            messages = reader.messages(connections=connections) if connections else iter(())
            n_total = sum(c.msgcount for c in connections)
            next_progress = time.monotonic() + PROGRESS_PERIOD_S
            for n, (conn, log_time_ns, raw) in enumerate(messages, 1):
                _convert_one(ts2, writer, report, conn, log_time_ns, raw, topic_map)
                if time.monotonic() >= next_progress:
                    log.info("converted %d of %d messages (%.0f %%)", n, n_total, 100 * n / max(n_total, 1))
                    next_progress = time.monotonic() + PROGRESS_PERIOD_S
            writer.add_metadata("sofia.source", {"bag": src.name, "converter": "sofia replay convert"})
    except ReaderError as e:
        dst.unlink(missing_ok=True)
        reason = str(e)
        if "index" in reason.lower():
            reason += "; " + REINDEX_HINT.format(name=src.name)
        raise BadBagError(src, reason) from None
    except BaseException:  # an interrupted or failed conversion leaves no partial MCAP
        dst.unlink(missing_ok=True)
        raise
    if report.n_written == 0:
        dst.unlink(missing_ok=True)
        raise NothingConvertedError(src, _why_nothing(bag_counts, topics, report))
    for topic, n in sorted(report.written.items()):
        log.info("wrote %d messages on %s", n, topic)
    return report


def _why_nothing(bag_counts: Counter[str], topics: list[str] | None, report: ConversionReport) -> str:
    """Why a conversion wrote no message, from the bag's topic counts and the report."""
    if sum(bag_counts.values()) == 0:
        return "the bag holds no message" + (
            f" (topics {', '.join(sorted(bag_counts))})" if bag_counts else ""
        )
    if report.rejected:
        return f"all {sum(report.rejected.values())} messages were rejected (see the warnings)"
    if topics is not None and not set(topics) & set(bag_counts):
        return f"no topic {', '.join(topics)} in the bag (its topics: {', '.join(sorted(bag_counts))})"
    if report.skipped_topics:
        skipped = ", ".join(f"{t} ({m})" for t, m in sorted(report.skipped_topics.items()))
        return f"no topic of a converted type (skipped {skipped}; converted: {', '.join(sorted(CONVERTED_TYPES))})"
    return "no message on the topics selected"


def _convert_one(
    ts2: Any, writer: McapWriter, report: ConversionReport, conn: Any, log_time_ns: int, raw: bytes,
    topic_map: dict[str, str],
) -> None:  # fmt: skip
    out_type = CONVERTED_TYPES[conn.msgtype]
    out_topic = topic_map.get(conn.topic, conn.topic)
    try:
        cdr = bytes(ts2.ros1_to_cdr(raw, out_type))
    except Exception as e:  # rosbags raises assorted errors on corrupt ROS 1 bytes
        report.rejected[conn.topic] += 1
        log.warning(
            "%s at %d ns: cannot convert %s (%d bytes): %s",
            conn.topic,
            log_time_ns,
            conn.msgtype,
            len(raw),
            e,
        )
        return
    if out_type == POINTCLOUD2:
        try:
            pointcloud.decode(cdr)
        except PointCloudError as e:
            report.rejected[conn.topic] += 1
            log.warning("%s at %d ns: cloud rejected: %s", conn.topic, log_time_ns, e)
            return
    writer.write_raw(out_topic, out_type, cdr, log_time_ns)
    report.written[out_topic] += 1
