"""Summary of an MCAP recording: topics, counts, schema names, time span (``sofia replay info``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from mcap.reader import McapReader


@dataclass
class TopicSummary:
    schema_name: str
    message_encoding: str
    count: int = 0


@dataclass
class RecordingSummary:
    """What ``sofia replay info`` prints."""

    path: str
    topics: dict[str, TopicSummary] = field(default_factory=dict)
    start_ns: int = 0
    end_ns: int = 0
    metadata: list[str] = field(default_factory=list)

    @property
    def n_messages(self) -> int:
        return sum(t.count for t in self.topics.values())

    @property
    def duration_s(self) -> float:
        return (self.end_ns - self.start_ns) / 1e9

    def to_dict(self) -> dict[str, Any]:
        return {
            "path": self.path,
            "n_messages": self.n_messages,
            "start_ns": self.start_ns,
            "end_ns": self.end_ns,
            "duration_s": self.duration_s,
            "topics": {
                t: {"schema": s.schema_name, "encoding": s.message_encoding, "count": s.count}
                for t, s in self.topics.items()
            },
            "metadata": self.metadata,
        }

    def format(self) -> str:
        lines = [
            f"file:      {self.path}",
            f"messages:  {self.n_messages}",
            f"duration:  {self.duration_s:.3f} s  (log time {self.start_ns} .. {self.end_ns} ns)",
            f"metadata:  {', '.join(self.metadata) or '-'}",
            "topics:",
        ]
        width = max((len(t) for t in self.topics), default=0)
        for topic, s in sorted(self.topics.items()):
            lines.append(f"  {topic:<{width}}  {s.count:>7}  {s.schema_name} ({s.message_encoding})")
        return "\n".join(lines)


def summarize(reader: McapReader, path: str) -> RecordingSummary:
    """Read the summary section (or, in a file without one, every message) of an open reader."""
    out = RecordingSummary(path=path)
    s = reader.get_summary()
    out.metadata = [m.name for m in reader.iter_metadata()]
    if s is not None and s.statistics is not None:
        for cid, ch in s.channels.items():
            schema = s.schemas.get(ch.schema_id)
            out.topics[ch.topic] = TopicSummary(
                schema_name=schema.name if schema else "",
                message_encoding=ch.message_encoding,
                count=s.statistics.channel_message_counts.get(cid, 0),
            )
        out.start_ns = s.statistics.message_start_time
        out.end_ns = s.statistics.message_end_time
        return out
    first: int | None = None
    for schema, ch, msg in reader.iter_messages(log_time_order=False):
        ts = out.topics.setdefault(ch.topic, TopicSummary(schema.name if schema else "", ch.message_encoding))
        ts.count += 1
        first = msg.log_time if first is None else min(first, msg.log_time)
        out.end_ns = max(out.end_ns, msg.log_time)
    out.start_ns = first or 0
    return out
