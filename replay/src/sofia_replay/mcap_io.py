"""MCAP recordings of the SofIA bus, readable by Foxglove and ROS 2 tools.

Layout: profile ``ros2``; every channel has a ``ros2msg`` schema (the ``.msg`` text of the ROS 2
type, from :func:`sofia_schemas.rosmsg.msgdef`) and ``cdr`` message encoding. Clouds are
``sensor_msgs/msg/PointCloud2`` on :data:`~sofia_schemas.keys.TOPIC_POINTS` (base frame) or
:data:`~sofia_schemas.keys.TOPIC_CAMERA_POINTS` (camera frame); flange poses
``geometry_msgs/msg/TransformStamped`` on :data:`~sofia_schemas.keys.TOPIC_FLANGE_POSE`; blob
observations ``geometry_msgs/msg/PointStamped`` on :data:`~sofia_schemas.keys.TOPIC_BLOB`.
Ground truth of synthetic recordings is JSON in the metadata record ``sofia.truth`` (key ``json``).

Readers are lazy iterators: messages are read chunk by chunk, never all at once. Time ranges are
log times in integer nanoseconds, ``start_ns`` inclusive and ``end_ns`` exclusive.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import IO, Any

from mcap.exceptions import McapError
from mcap.reader import McapReader, make_reader
from mcap.well_known import MessageEncoding, Profile, SchemaEncoding
from mcap.writer import CompressionType, Writer
from sofia_schemas import pointcloud, rosmsg
from sofia_schemas.keys import TOPIC_BLOB, TOPIC_FLANGE_POSE
from sofia_schemas.messages import BlobObservation, FlangePose
from sofia_schemas.pointcloud import PointCloud2

from .errors import BadTruthError, NotAnMcapError, RecordingError, RecordingNotFoundError, UnknownSchemaError
from .mcap_summary import RecordingSummary, summarize

TRUTH_METADATA = "sofia.truth"
TRUTH_KEY = "json"
# what the mcap package raises on a corrupt or truncated file
MCAP_ERRORS = (McapError, ValueError, EOFError, struct.error, OSError)  # OSError: a seek before the start
KNOWN_STARTS = {b"#ROSBAG": "a ROS 1 bag (`sofia replay convert` turns it into MCAP)",
                b"SQLite format": "an SQLite database (a ROS 2 .db3 bag?), not MCAP"}  # fmt: skip


def why_not_mcap(path: str | Path, error: BaseException) -> str:
    """What is wrong with a file the MCAP reader refused, in words (not the reader's tuple of bytes)."""
    text = str(error)
    if "magic" in text:
        try:
            with open(path, "rb") as f:
                head = f.read(16)
        except OSError:
            head = b""
        known = next((what for start, what in KNOWN_STARTS.items() if head.startswith(start)), None)
        return known or "it does not start with the MCAP magic bytes (is it an MCAP recording?)"
    if isinstance(error, OSError | EOFError | struct.error):
        return f"it ends early ({Path(path).stat().st_size} bytes): truncated or still being written"
    return text or type(error).__name__


COMPRESSIONS = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}


@dataclass(frozen=True)
class RecordedMessage:
    """One recorded message: ``data`` is the CDR bytes exactly as recorded."""

    topic: str
    schema_name: str
    log_time_ns: int
    publish_time_ns: int
    data: bytes


class McapWriter:
    """Write a SofIA recording (context manager; the file is complete after ``close``).

    >>> with McapWriter("out.mcap") as w:  # doctest: +SKIP
    ...     w.write_cloud(TOPIC_POINTS, cdr, log_time_ns=cloud_stamp_ns)
    """

    def __init__(
        self, path: str | Path, compression: str = "zstd", chunk_size: int = 4 * 1024 * 1024
    ) -> None:
        if compression not in COMPRESSIONS:
            raise RecordingError(f"compression {compression!r} is not one of {sorted(COMPRESSIONS)}")
        self.path = Path(path)
        self._file: IO[bytes] = open(self.path, "wb")  # closed in close()
        self._writer = Writer(self._file, compression=COMPRESSIONS[compression], chunk_size=chunk_size)
        self._writer.start(profile=Profile.ROS2, library="sofia_replay")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, tuple[int, str]] = {}
        self._sequence: dict[int, int] = {}
        self._closed = False

    # --- context manager --------------------------------------------------
    def __enter__(self) -> McapWriter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def close(self) -> None:
        """Write the summary and indexes and close the file."""
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.finish()
        finally:
            self._file.close()

    # --- channels ---------------------------------------------------------
    def _channel(self, topic: str, typename: str) -> int:
        known = self._channels.get(topic)
        if known is not None:
            if known[1] != typename:
                raise RecordingError(f"topic {topic!r} already carries {known[1]}, cannot write {typename}")
            return known[0]
        schema_id = self._schemas.get(typename)
        if schema_id is None:
            try:
                text = rosmsg.msgdef(typename)
            except Exception as e:  # rosbags raises KeyError or its own TypesysError
                raise UnknownSchemaError(typename) from e
            schema_id = self._writer.register_schema(typename, SchemaEncoding.ROS2, text.encode())
            self._schemas[typename] = schema_id
        channel_id = self._writer.register_channel(topic, MessageEncoding.CDR, schema_id)
        self._channels[topic] = (channel_id, typename)
        return channel_id

    # --- messages ---------------------------------------------------------
    def write_raw(
        self, topic: str, typename: str, cdr: bytes | bytearray | memoryview, log_time_ns: int,
        publish_time_ns: int | None = None,
    ) -> None:  # fmt: skip
        """Write CDR bytes of ROS 2 type ``typename`` (e.g. ``geometry_msgs/msg/PoseStamped``)."""
        if self._closed:
            raise RecordingError(f"{self.path} is closed")
        channel_id = self._channel(topic, typename)
        seq = self._sequence.get(channel_id, 0)
        self._sequence[channel_id] = seq + 1
        self._writer.add_message(
            channel_id=channel_id,
            log_time=int(log_time_ns),
            data=bytes(cdr),
            publish_time=int(log_time_ns if publish_time_ns is None else publish_time_ns),
            sequence=seq,
        )

    def write_cloud(
        self, topic: str, cdr: bytes | bytearray | memoryview, log_time_ns: int,
        publish_time_ns: int | None = None,
    ) -> None:  # fmt: skip
        """Write a CDR ``sensor_msgs/msg/PointCloud2`` (e.g. from ``pointcloud.encode_points``)."""
        self.write_raw(topic, rosmsg.POINTCLOUD2, cdr, log_time_ns, publish_time_ns)

    def write_flange_pose(self, topic: str, pose: FlangePose, log_time_ns: int | None = None) -> None:
        """Write ``T_base_flange`` as a CDR TransformStamped; log time defaults to its stamp."""
        t_ns = pose.stamp_ns if log_time_ns is None else log_time_ns
        self.write_raw(topic, rosmsg.TRANSFORM_STAMPED, rosmsg.encode_flange_pose(pose), t_ns)

    def write_blob(self, topic: str, obs: BlobObservation, log_time_ns: int | None = None) -> None:
        """Write a camera-frame blob position as a CDR PointStamped; log time defaults to its stamp."""
        t_ns = obs.stamp_ns if log_time_ns is None else log_time_ns
        self.write_raw(topic, rosmsg.POINT_STAMPED, rosmsg.encode_blob(obs), t_ns)

    # --- metadata ---------------------------------------------------------
    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        bad = {k: type(v).__name__ for k, v in data.items() if not isinstance(v, str)}
        if bad:
            raise RecordingError(f"metadata {name!r} values must be strings, got {bad}")
        self._writer.add_metadata(name, dict(data))

    def add_truth(self, obj: dict[str, Any]) -> None:
        """Store ground truth as JSON in metadata ``sofia.truth`` (key ``json``)."""
        self.add_metadata(TRUTH_METADATA, {TRUTH_KEY: json.dumps(obj)})


# --- reading ----------------------------------------------------------------
def _open(path: str | Path) -> tuple[IO[bytes], McapReader]:
    path = Path(path)
    if not path.is_file():
        raise RecordingNotFoundError(path)
    f = open(path, "rb")  # closed by the callers
    try:
        return f, make_reader(f)
    except MCAP_ERRORS as e:
        f.close()
        raise NotAnMcapError(path, why_not_mcap(path, e)) from None


def iter_messages(
    path: str | Path, topics: Iterable[str] | None = None, start_ns: int | None = None,
    end_ns: int | None = None,
) -> Iterator[RecordedMessage]:  # fmt: skip
    """Recorded messages in log-time order, read lazily, ``start_ns <= log_time < end_ns``."""
    topic_list = None if topics is None else list(topics)
    f, reader = _open(path)
    with f:
        try:
            for schema, channel, message in reader.iter_messages(
                topics=topic_list, starting_at=start_ns, ending_before=end_ns
            ):
                yield RecordedMessage(
                    topic=channel.topic,
                    schema_name=schema.name if schema is not None else "",
                    log_time_ns=message.log_time,
                    publish_time_ns=message.publish_time,
                    data=message.data,
                )
        except MCAP_ERRORS as e:
            raise NotAnMcapError(path, why_not_mcap(path, e)) from None


def iter_clouds(
    path: str | Path, topics: Iterable[str] | None = None, start_ns: int | None = None,
    end_ns: int | None = None,
) -> Iterator[tuple[str, int, PointCloud2]]:  # fmt: skip
    """``(topic, log_time_ns, cloud)`` for every PointCloud2 message; clouds view the read bytes."""
    cloud_topics = [t for t, s in summary(path).topics.items() if s.schema_name == rosmsg.POINTCLOUD2]
    if topics is not None:
        wanted = set(topics)
        cloud_topics = [t for t in cloud_topics if t in wanted]
    if not cloud_topics:
        return
    for m in iter_messages(path, cloud_topics, start_ns, end_ns):
        yield m.topic, m.log_time_ns, pointcloud.decode(m.data)


def iter_flange_poses(path: str | Path, topic: str = TOPIC_FLANGE_POSE) -> Iterator[tuple[int, FlangePose]]:
    """``(log_time_ns, pose)`` of the recorded flange poses."""
    for m in iter_messages(path, [topic]):
        yield m.log_time_ns, rosmsg.decode_flange_pose(m.data)


def iter_blobs(path: str | Path, topic: str = TOPIC_BLOB) -> Iterator[tuple[int, BlobObservation]]:
    """``(log_time_ns, observation)`` of the recorded blob observations."""
    for m in iter_messages(path, [topic]):
        yield m.log_time_ns, rosmsg.decode_blob(m.data)


def read_metadata(path: str | Path) -> dict[str, dict[str, str]]:
    """Every metadata record, by name (a later record of the same name wins)."""
    f, reader = _open(path)
    with f:
        try:
            return {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        except MCAP_ERRORS as e:
            raise NotAnMcapError(path, why_not_mcap(path, e)) from None


def read_truth(path: str | Path) -> dict[str, Any] | None:
    """The ground truth stored by :meth:`McapWriter.add_truth`, or None."""
    record = read_metadata(path).get(TRUTH_METADATA)
    if record is None:
        return None
    if TRUTH_KEY not in record:
        raise BadTruthError(
            path, f"metadata {TRUTH_METADATA!r} has no key {TRUTH_KEY!r} (keys {sorted(record)})"
        )
    try:
        obj = json.loads(record[TRUTH_KEY])
    except json.JSONDecodeError as e:
        raise BadTruthError(path, str(e)) from None
    if not isinstance(obj, dict):
        raise BadTruthError(path, f"expected a JSON object, got {type(obj).__name__}")
    return obj


# --- summary ----------------------------------------------------------------
def summary(path: str | Path) -> RecordingSummary:
    """Topics, message counts, schema names and time span, from the summary section when present."""
    f, reader = _open(path)
    with f:
        try:
            return summarize(reader, str(path))
        except MCAP_ERRORS as e:
            raise NotAnMcapError(path, why_not_mcap(path, e)) from None
