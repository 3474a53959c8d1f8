"""One recorded message out of an MCAP file, as the bytes it was recorded with.

``sofia replay export FILE.mcap --topic /pc_glob --index 3 --out cloud.cdr`` writes the CDR
payload of the fourth base-frame cloud: what ``sofia query sofia/panda/detector/detect --payload
cloud.cdr`` sends to the detector.
"""

from __future__ import annotations

from pathlib import Path

from sofia_schemas.keys import TOPIC_CAMERA_POINTS, TOPIC_POINTS
from sofia_schemas.rosmsg import POINTCLOUD2

from .errors import NoSuchMessageError, NoSuchTopicError
from .mcap_io import RecordedMessage, iter_messages, summary


def default_topic(path: str | Path) -> str:
    """The cloud topic exported when none is named: the base-frame clouds, else the camera-frame
    clouds, else the only cloud topic; NoSuchTopicError lists the topics when there is none."""
    topics = summary(path).topics
    clouds = sorted(t for t, s in topics.items() if s.schema_name == POINTCLOUD2)
    for preferred in (TOPIC_POINTS, TOPIC_CAMERA_POINTS):
        if preferred in clouds:
            return preferred
    if clouds:
        return clouds[0]
    raise NoSuchTopicError(path, ["of type " + POINTCLOUD2], sorted(topics))


def read_message(path: str | Path, topic: str, index: int = 0) -> RecordedMessage:
    """Message ``index`` (0 = first in log-time order; negative counts from the end) on ``topic``."""
    topics = summary(path).topics
    if topic not in topics:
        raise NoSuchTopicError(path, [topic], sorted(topics))
    count = topics[topic].count
    i = index + count if index < 0 else index
    if not 0 <= i < count:
        raise NoSuchMessageError(path, topic, index, count)
    n_seen = 0
    for message in iter_messages(path, [topic]):
        if n_seen == i:
            return message
        n_seen += 1
    raise NoSuchMessageError(path, topic, index, n_seen)  # the summary counted more than the file holds


def export_message(
    path: str | Path, out: str | Path, topic: str | None = None, index: int = 0
) -> RecordedMessage:
    """Write the payload of one message of ``path`` to ``out`` (parent folders made); returns it."""
    message = read_message(path, topic or default_topic(path), index)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_bytes(message.data)
    return message
