"""ROS 2 message types from the definitions shipped in ``sofia_schemas/data/msgs``.

- :func:`type_hash`: the RIHS01 type hash of a message or service type (REP 2011), computed from
  the ``.msg``/``.srv`` text the same way ``rosidl_generator_type_description`` does: the type
  description (field names, type ids, capacities, nested type names; no constants, no default
  values, no comments) of the type and of every type it references, sorted by name, as JSON with
  ``", "`` and ``": "`` separators, then SHA-256.
- :func:`typestore`: a ``rosbags`` type store with every shipped type registered, for CDR.
- :func:`dds_type_name`: ``pkg/msg/Name`` -> ``pkg::msg::dds_::Name_`` (rmw_zenoh key and tokens).

Nothing is downloaded: a type that is not shipped raises :class:`UnknownRosTypeError`.
"""

from __future__ import annotations

import hashlib
import json
import re
from functools import cache, lru_cache
from pathlib import Path
from typing import Any

from ..errors import SofiaError

MSGS_DIR = Path(__file__).resolve().parents[1] / "data" / "msgs"
EMPTY_MEMBER = "structure_needs_at_least_one_member"

_PRIMITIVE_IDS = {
    "int8": 2, "uint8": 3, "char": 3, "int16": 4, "uint16": 5, "int32": 6, "uint32": 7, "int64": 8,
    "uint64": 9, "float32": 10, "float64": 11, "bool": 15, "byte": 16, "string": 17, "wstring": 18,
}  # fmt: skip
_NESTED, _BOUNDED_STRING, _BOUNDED_WSTRING = 1, 21, 22
_ARRAY, _BOUNDED_SEQ, _UNBOUNDED_SEQ = 48, 96, 144  # added to the element's id
_ARRAY_RE = re.compile(r"^(?P<base>[^\[]+)(?:\[(?P<bound><=)?(?P<size>\d*)\])?$")


class UnknownRosTypeError(SofiaError, LookupError):
    def __init__(self, typename: str) -> None:
        super().__init__(
            f"ROS type {typename!r} is not shipped in {MSGS_DIR} (expected <package>/msg/<Name>.msg "
            "or <package>/srv/<Name>.srv)"
        )


def _split_type(typename: str) -> tuple[str, str, str]:
    parts = typename.split("/")
    if len(parts) != 3 or parts[1] not in ("msg", "srv"):
        raise UnknownRosTypeError(typename)
    return parts[0], parts[1], parts[2]


@cache
def definition(typename: str) -> str:
    """The ``.msg`` text of ``pkg/msg/Name``, or of a service part ``pkg/srv/Name_Request`` /
    ``pkg/srv/Name_Response``, or the whole ``.srv`` text of ``pkg/srv/Name``."""
    pkg, kind, name = _split_type(typename)
    if kind == "msg":
        path = MSGS_DIR / pkg / "msg" / f"{name}.msg"
        if not path.is_file():
            raise UnknownRosTypeError(typename)
        return path.read_text()
    base, _, part = name.rpartition("_")
    if part in ("Request", "Response"):
        request, response = _split_srv(definition(f"{pkg}/srv/{base}"))
        return request if part == "Request" else response
    path = MSGS_DIR / pkg / "srv" / f"{name}.srv"
    if not path.is_file():
        raise UnknownRosTypeError(typename)
    return path.read_text()


def _split_srv(text: str) -> tuple[str, str]:
    lines = text.splitlines()
    sep = [i for i, line in enumerate(lines) if line.strip() == "---"]
    if len(sep) != 1:
        raise ValueError(f"a .srv definition needs exactly one '---' line, found {len(sep)}")
    return "\n".join(lines[: sep[0]]) + "\n", "\n".join(lines[sep[0] + 1 :]) + "\n"


def _resolve(name: str, package: str) -> str:
    parts = name.split("/")
    if len(parts) == 1:
        return f"{package}/msg/{name}"
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    return name


def fields(typename: str) -> list[dict[str, Any]]:
    """Type-description fields of ``typename``: ``{"name", "type": {type_id, capacity,
    string_capacity, nested_type_name}}`` in declaration order (constants left out)."""
    package = typename.split("/")[0]
    out: list[dict[str, Any]] = []
    for raw in definition(typename).splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        tokens = line.split()
        if len(tokens) < 2:
            raise ValueError(f"{typename}: cannot parse line {raw!r}")
        if "=" in tokens[1] or (len(tokens) > 2 and tokens[2].startswith("=")):
            continue  # a constant
        match = _ARRAY_RE.match(tokens[0])
        if match is None:
            raise ValueError(f"{typename}: cannot parse type {tokens[0]!r}")
        base, string_capacity = match["base"], 0
        if base.startswith(("string<=", "wstring<=")):
            base, cap = base.split("<=")
            string_capacity = int(cap)
        if base in _PRIMITIVE_IDS:
            type_id, nested = _PRIMITIVE_IDS[base], ""
            if string_capacity:
                type_id = _BOUNDED_WSTRING if base == "wstring" else _BOUNDED_STRING
        else:
            type_id, nested = _NESTED, _resolve(base, package)
        capacity = 0
        if "[" in tokens[0]:
            size = match["size"]
            if match["bound"]:
                type_id, capacity = type_id + _BOUNDED_SEQ, int(size)
            elif size:
                type_id, capacity = type_id + _ARRAY, int(size)
            else:
                type_id += _UNBOUNDED_SEQ
        out.append({
            "name": tokens[1],
            "type": {"type_id": type_id, "capacity": capacity, "string_capacity": string_capacity,
                     "nested_type_name": nested},
        })  # fmt: skip
    if not out:
        out.append({"name": EMPTY_MEMBER, "type": _plain(_PRIMITIVE_IDS["uint8"])})
    return out


def _plain(type_id: int, nested: str = "", capacity: int = 0) -> dict[str, Any]:
    return {"type_id": type_id, "capacity": capacity, "string_capacity": 0, "nested_type_name": nested}


def _service_descriptions(typename: str) -> dict[str, dict[str, Any]]:
    """The synthetic types of a service: the service itself, its Event, and the parts."""
    request, response, event = (f"{typename}_{p}" for p in ("Request", "Response", "Event"))
    described = {
        typename: [
            {"name": "request_message", "type": _plain(_NESTED, request)},
            {"name": "response_message", "type": _plain(_NESTED, response)},
            {"name": "event_message", "type": _plain(_NESTED, event)},
        ],
        event: [
            {"name": "info", "type": _plain(_NESTED, "service_msgs/msg/ServiceEventInfo")},
            {"name": "request", "type": _plain(_NESTED + _BOUNDED_SEQ, request, 1)},
            {"name": "response", "type": _plain(_NESTED + _BOUNDED_SEQ, response, 1)},
        ],
    }
    return {name: {"type_name": name, "fields": f} for name, f in described.items()}


@cache
def type_description(typename: str) -> dict[str, Any]:
    """``{"type_description": ..., "referenced_type_descriptions": [...]}`` of ``typename``."""
    is_service = _split_type(typename)[1] == "srv" and not typename.endswith(("_Request", "_Response"))
    synthetic = _service_descriptions(typename) if is_service else {}

    def describe(name: str) -> dict[str, Any]:
        return synthetic[name] if name in synthetic else {"type_name": name, "fields": fields(name)}

    main = describe(typename)
    seen: dict[str, dict[str, Any]] = {}
    queue = [f["type"]["nested_type_name"] for f in main["fields"]]
    while queue:
        name = queue.pop()
        if name and name not in seen:
            seen[name] = describe(name)
            queue.extend(f["type"]["nested_type_name"] for f in seen[name]["fields"])
    return {"type_description": main, "referenced_type_descriptions": [seen[n] for n in sorted(seen)]}


@cache
def type_hash(typename: str) -> str:
    """``RIHS01_<sha256 hex>`` of a shipped message (``pkg/msg/Name``) or service (``pkg/srv/Name``).

    >>> type_hash("sensor_msgs/msg/PointCloud2")[:15]
    'RIHS01_9198cabf'
    """
    text = json.dumps(type_description(typename), separators=(", ", ": "), ensure_ascii=True)
    return "RIHS01_" + hashlib.sha256(text.encode()).hexdigest()


def dds_type_name(typename: str) -> str:
    """``pkg/msg/Name`` -> ``pkg::msg::dds_::Name_`` (the type name rmw_zenoh puts in keys)."""
    pkg, kind, name = _split_type(typename)
    return f"{pkg}::{kind}::dds_::{name}_"


def shipped_types() -> list[str]:
    """Every ``pkg/msg/Name`` and ``pkg/srv/Name`` shipped."""
    out = [f"{p.parent.parent.name}/msg/{p.stem}" for p in MSGS_DIR.glob("*/msg/*.msg")]
    out += [f"{p.parent.parent.name}/srv/{p.stem}" for p in MSGS_DIR.glob("*/srv/*.srv")]
    return sorted(out)


@lru_cache(maxsize=1)
def typestore() -> Any:
    """A ``rosbags`` type store holding every shipped message and service part."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)
    types: dict[str, Any] = {}
    for name in shipped_types():
        parts = [f"{name}_Request", f"{name}_Response"] if "/srv/" in name else [name]
        for part in parts:
            types.update(get_types_from_msg(definition(part), part))
    store.register(types)
    return store


def _stored(typename: str) -> str:
    """The name ``rosbags`` registers a type under (service parts get ``pkg/srv/msg/Name_Part``)."""
    pkg, kind, name = _split_type(typename)
    return f"{pkg}/srv/msg/{name}" if kind == "srv" else typename


def encode(msg: Any, typename: str) -> bytes:
    """CDR (little endian, with the encapsulation header) of a ``rosbags`` message object."""
    return bytes(typestore().serialize_cdr(msg, _stored(typename)))


def decode(payload: bytes | bytearray | memoryview, typename: str) -> Any:
    """A ``rosbags`` message object from CDR bytes; ``ValueError`` naming the type if they are bad."""
    try:
        return typestore().deserialize_cdr(bytes(payload), _stored(typename))
    except Exception as e:  # rosbags raises assorted errors on corrupt CDR
        raise ValueError(f"payload ({len(payload)} bytes) is not CDR {typename}: {e}") from None


def new(typename: str, **values: Any) -> Any:
    """A message object of ``typename`` (``rosbags`` dataclass) from keyword values."""
    return typestore().types[_stored(typename)](**values)
