"""Detect queries that select objects: ``{"colour": "yellow"}`` answers with the yellow objects of
the latest cloud; the lab's one-centroid-per-colour answer is one such query per colour."""

from __future__ import annotations

import json

from sofia_schemas.messages import Detection

from .errors import BadSelection
from .params import DEFAULT_PALETTE


def split_selection(
    payload: bytes, palette: tuple[tuple[str, tuple[int, int, int]], ...] = DEFAULT_PALETTE
) -> tuple[str | None, bytes]:
    """(colour selected, cloud payload) of a detect query's payload.

    A payload starting with ``{`` is a JSON selection about the latest cloud (the cloud payload is
    then empty); anything else (JSON that does not parse included) is taken as a CDR PointCloud2
    (or nothing) without selection. Raises :class:`BadSelection` for unknown keys or a colour
    outside ``palette``.
    """
    if not payload.lstrip().startswith(b"{"):
        return None, payload
    try:
        data = json.loads(payload)
    except (UnicodeDecodeError, json.JSONDecodeError):
        return None, payload  # not a selection: the cloud decoder says what is wrong with it
    if not isinstance(data, dict):
        raise BadSelection(f"expected a JSON object, got {type(data).__name__}")
    if not data or set(data) - {"colour", "color"}:
        raise BadSelection(f'expected {{"colour": NAME}}, got keys {sorted(data)}')
    colour = data.get("colour", data.get("color"))
    names = [n for n, _ in palette]
    if colour not in names:
        raise BadSelection(f"colour {colour!r} is not one of {names}")
    return str(colour), b""


def select(det: Detection, colour: str | None) -> Detection:
    """``det`` with only the objects of ``colour`` (status ``no_object`` when none is left)."""
    if colour is None:
        return det
    objects = [o for o in det.objects if o.colour == colour]
    status = det.status if det.status == "no_board" else ("ok" if objects else "no_object")
    return det.model_copy(update={"objects": objects, "status": status})
