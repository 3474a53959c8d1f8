"""The rmw_zenoh wire protocol (ROS 2 Jazzy and later), on a zenoh-python session.

What an ``RMW_IMPLEMENTATION=rmw_zenoh_cpp`` node expects from a peer:

- data keys ``<domain>/<topic without leading slash>/<pkg::msg::dds_::Name_>/<RIHS01 type hash>``
  (services the same with the service name and the service's type and hash);
- on every sample, request and reply an attachment: ``int64 sequence_number``, ``int64
  source_timestamp`` (ns), then the 16-byte source gid as a length-prefixed buffer (zenoh's
  serializer: ``<q``, ``<q``, LEB128 length, bytes); a reply repeats the request's sequence number
  and the client's gid;
- graph discovery by liveliness tokens ``@ros2_lv/<domain>/<zid>/<node id>/<entity id>/<kind>/
  <enclave>/<namespace>/<node>[/<name>/<type>/<hash>/<qos>]`` with ``/`` in names written ``%``,
  kinds ``NN`` (node), ``MP``/``MS`` (publisher/subscription), ``SS``/``SC`` (service/client), and
  the QoS as ``<reliability>:<durability>:<history>,<depth>:<deadline>:<lifespan>:<liveliness>``
  (empty = default: reliable, volatile, keep last);
- transient-local publishers (``/tf_static``) keep their last samples in a zenoh-ext advanced
  publisher cache, which late subscribers query; reliable ones also send a sporadic heartbeat
  (their last sequence number, every :data:`SAMPLE_MISS_HEARTBEAT_S` when it changed) so a
  subscriber that lost the last sample detects it and recovers it from the cache.
"""

from __future__ import annotations

import itertools
import logging
import os
import secrets
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import zenoh
import zenoh.ext
from sofia_schemas.errors import PayloadError
from sofia_schemas.ros2.typesupport import dds_type_name, type_hash

log = logging.getLogger("sofia.ros2")
GID_SIZE = 16
DOMAIN_ENV = "ROS_DOMAIN_ID"
SAMPLE_MISS_HEARTBEAT_S = 0.5  # rmw_zenoh's SAMPLE_MISS_DETECTION_HEARTBEAT_PERIOD (500 ms)
_KEYED = b"\x0fsequence_number"  # the attachment of rmw_zenoh before 0.2.4 named its fields


def domain_id() -> int:
    """``$ROS_DOMAIN_ID`` (default 0)."""
    return int(os.environ.get(DOMAIN_ENV, "0") or 0)


def mangle(name: str) -> str:
    """``/sofia/panda/points`` -> ``%sofia%panda%points`` (names inside liveliness tokens)."""
    return name.replace("/", "%")


def data_key(domain: int, name: str, typename: str) -> str:
    """The key expression of a topic or service: ``<domain>/<name>/<dds type>/<type hash>``."""
    return f"{domain}/{name.strip('/')}/{dds_type_name(typename)}/{type_hash(typename)}"


@dataclass(frozen=True)
class Qos:
    """The QoS a ROS 2 endpoint announces (and, for transient local, serves)."""

    reliable: bool = True
    transient_local: bool = False
    depth: int = 10
    block: bool = False  # congestion control BLOCK (lossless large samples) instead of DROP

    def encode(self) -> str:
        reliability = "" if self.reliable else "2"
        durability = "1" if self.transient_local else ""
        return f"{reliability}:{durability}:,{self.depth}:,:,:,,"


SENSOR_QOS = Qos(reliable=False, depth=5)
STATIC_QOS = Qos(transient_local=True, depth=1)


@dataclass(frozen=True)
class Attachment:
    """rmw_zenoh's attachment: compact (0.2.4 and later) or ``keyed`` (0.2.0-0.2.3, each field
    preceded by its name). SofIA publishes the compact form and answers a request in its form."""

    sequence_number: int
    source_timestamp_ns: int
    source_gid: bytes
    keyed: bool = False

    def encode(self) -> bytes:
        if self.keyed:
            return (
                _KEYED + struct.pack("<q", self.sequence_number)
                + b"\x10source_timestamp" + struct.pack("<q", self.source_timestamp_ns)
                + b"\x0asource_gid" + bytes([len(self.source_gid)]) + self.source_gid
            )  # fmt: skip
        return struct.pack("<qqB", self.sequence_number, self.source_timestamp_ns, GID_SIZE) + self.source_gid

    @classmethod
    def decode(cls, raw: bytes) -> Attachment:
        """Parse the compact attachment (or the older one with field names); PayloadError if bad."""
        if raw.startswith(_KEYED):
            return cls._decode_keyed(raw)
        if len(raw) != 17 + GID_SIZE or raw[16] != GID_SIZE:
            raise PayloadError(
                f"rmw_zenoh attachment of {len(raw)} bytes: expected 33 (seq, stamp, 16-byte gid)"
            )
        seq, stamp = struct.unpack_from("<qq", raw)
        return cls(seq, stamp, bytes(raw[17:]))

    @classmethod
    def _decode_keyed(cls, raw: bytes) -> Attachment:
        pos, values = 0, []
        for name in (b"sequence_number", b"source_timestamp", b"source_gid"):
            if raw[pos : pos + 1 + len(name)] != bytes([len(name)]) + name:
                raise PayloadError(f"rmw_zenoh attachment: field {name.decode()} missing")
            pos += 1 + len(name)
            if name == b"source_gid":
                n = raw[pos]
                values.append(bytes(raw[pos + 1 : pos + 1 + n]))
            else:
                values.append(struct.unpack_from("<q", raw, pos)[0])
                pos += 8
        return cls(int(values[0]), int(values[1]), bytes(values[2]), keyed=True)


def sample_attachment(sample: zenoh.Sample | zenoh.Query) -> Attachment | None:
    """The rmw_zenoh attachment of a sample or query, None when it has none or a bad one."""
    if sample.attachment is None:
        return None
    try:
        return Attachment.decode(sample.attachment.to_bytes())
    except PayloadError:
        return None


class Graph:
    """The ROS 2 entities declared on one Zenoh session (ids, gids, the domain)."""

    def __init__(self, session: zenoh.Session, domain: int | None = None) -> None:
        self.session = session
        self.domain = domain_id() if domain is None else domain
        self.zid = str(session.info.zid())
        self._ids = itertools.count()
        self.own_gids: set[bytes] = set()

    def next_id(self) -> int:
        return next(self._ids)

    def new_gid(self) -> bytes:
        gid = secrets.token_bytes(GID_SIZE)
        self.own_gids.add(gid)
        return gid

    def node(self, name: str, namespace: str = "/") -> Node:
        return Node(self, name, namespace)


class Node:
    """A ROS 2 node: its liveliness token and the endpoints it declares."""

    def __init__(self, graph: Graph, name: str, namespace: str = "/") -> None:
        self.graph, self.name, self.namespace = graph, name, namespace
        self.node_id = graph.next_id()
        self._declared: list[Any] = []
        self._token(self.node_id, "NN", "")

    def _token(self, entity_id: int, kind: str, tail: str) -> None:
        g = self.graph
        key = (
            f"@ros2_lv/{g.domain}/{g.zid}/{self.node_id}/{entity_id}/{kind}/%/"
            f"{mangle(self.namespace)}/{self.name}{tail}"
        )
        self._declared.append(g.session.liveliness().declare_token(key))

    def _endpoint(self, kind: str, name: str, typename: str, qos: Qos) -> str:
        tail = f"/{mangle(name)}/{dds_type_name(typename)}/{type_hash(typename)}/{qos.encode()}"
        self._token(self.graph.next_id(), kind, tail)
        return data_key(self.graph.domain, name, typename)

    def publisher(self, topic: str, typename: str, qos: Qos = Qos()) -> Publisher:
        key = self._endpoint("MP", topic, typename, qos)
        pub = Publisher(self.graph, key, qos)
        self._declared.append(pub)
        return pub

    def subscription(
        self,
        topic: str,
        typename: str,
        callback: Callable[[bytes, Attachment | None], None],
        qos: Qos = Qos(),
    ) -> None:
        """``callback(cdr_bytes, attachment)`` for every sample not published by this session's
        own endpoints (so a topic both published and subscribed here does not loop)."""
        key = self._endpoint("MS", topic, typename, qos)
        own = self.graph.own_gids

        def listener(sample: zenoh.Sample) -> None:
            att = sample_attachment(sample)
            if att is not None and att.source_gid in own:
                return
            callback(sample.payload.to_bytes(), att)

        self._declared.append(self.graph.session.declare_subscriber(key, listener))

    def service(self, name: str, typename: str, handler: Callable[[zenoh.Query], None]) -> str:
        """A service server: ``handler(query)`` runs on Zenoh's thread and must only hand over."""
        key = self._endpoint("SS", name, typename, Qos())
        self._declared.append(self.graph.session.declare_queryable(key, handler, complete=True))
        return key

    def close(self) -> None:
        for d in reversed(self._declared):
            try:
                d.undeclare()
            except Exception as e:  # already closed with the session
                log.debug("undeclare %s: %s", d, e)
        self._declared.clear()


class Publisher:
    """Puts CDR with the rmw_zenoh attachment; transient-local ones keep a cache for late joiners."""

    def __init__(self, graph: Graph, key: str, qos: Qos) -> None:
        self.key = key
        self.gid = graph.new_gid()
        self._seq = itertools.count(1)
        self._lock = threading.Lock()
        self._pub: Any
        if qos.transient_local:
            # as rmw_zenoh: reliable + transient local also detect sample misses (sporadic heartbeat)
            miss = zenoh.ext.MissDetectionConfig(heartbeat=None, sporadic_heartbeat=SAMPLE_MISS_HEARTBEAT_S)
            self._pub = zenoh.ext.declare_advanced_publisher(
                graph.session,
                key,
                cache=zenoh.ext.CacheConfig(max_samples=qos.depth),
                publisher_detection=True,
                sample_miss_detection=miss if qos.reliable else None,
            )
        else:
            cc = zenoh.CongestionControl.BLOCK if qos.block else zenoh.CongestionControl.DROP
            self._pub = graph.session.declare_publisher(key, congestion_control=cc)

    def put(self, cdr: bytes) -> None:
        with self._lock:
            att = Attachment(next(self._seq), time.time_ns(), self.gid)
            self._pub.put(cdr, attachment=att.encode())

    def undeclare(self) -> None:
        self._pub.undeclare()


def reply(query: zenoh.Query, request: Attachment, cdr: bytes) -> None:
    """Answer a service request: the response CDR, the request's sequence number and client gid."""
    att = Attachment(request.sequence_number, time.time_ns(), request.source_gid, keyed=request.keyed)
    try:
        query.reply(query.key_expr, cdr, attachment=att.encode())
    finally:
        query.drop()
