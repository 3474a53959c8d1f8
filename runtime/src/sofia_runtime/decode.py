"""Turn any SofIA bus payload into something a person can read (``sofia echo``, ``sofia query``)."""

from __future__ import annotations

import json
from typing import Any

from sofia_schemas import pointcloud, rosmsg
from sofia_schemas.errors import PayloadError, PointCloudError


def describe(payload: bytes, encoding: str = "") -> dict[str, Any]:
    """A JSON-able description of ``payload``.

    JSON payloads are parsed; CDR point clouds are summarised (size, fields, finite points,
    bounds); CDR flange poses and blob observations are decoded; anything else is shown as a
    hex preview with its size.
    """
    enc = encoding or ""
    if payload[:1] in (b"{", b"["):
        try:
            return {"json": json.loads(payload)}
        except ValueError:
            pass
    if "PointCloud2" in enc or (not enc.startswith("application/json") and payload[:2] == b"\x00\x01"):
        try:
            cloud = pointcloud.decode(payload)
            summary = pointcloud.info(cloud)
            xyz = cloud.xyz().reshape(-1, 3)
            finite = xyz[(xyz == xyz).all(axis=1)]
            if len(finite):
                summary["min"] = [round(float(v), 4) for v in finite.min(axis=0)]
                summary["max"] = [round(float(v), 4) for v in finite.max(axis=0)]
            return {"point_cloud": summary}
        except PointCloudError as e:
            if "PointCloud2" in enc:
                return {"error": str(e), "bytes": len(payload)}
    for name, fn in (("flange_pose", rosmsg.decode_flange_pose), ("blob", rosmsg.decode_blob)):
        if name == "flange_pose" and "PointStamped" in enc:
            continue
        try:
            return {name: json.loads(fn(payload).model_dump_json())}
        except (PayloadError, ImportError):
            continue
    return {"bytes": len(payload), "hex": payload[:32].hex() + ("…" if len(payload) > 32 else "")}
