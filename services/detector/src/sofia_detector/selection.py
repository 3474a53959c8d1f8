"""Detect queries that select objects: ``{"colour": "yellow"}`` answers with the yellow objects of
the latest cloud; the lab's one-centroid-per-colour answer is one such query per colour."""

from __future__ import annotations

import json
from dataclasses import dataclass

from sofia_schemas.messages import Detection

from .errors import DetectorError
from .params import DEFAULT_PALETTE

KNOWN = ("colour", "color")


class BadSelection(DetectorError):  # noqa: N818 - public API name
    """A detect query's JSON selection cannot be understood."""

    def __init__(self, what: str) -> None:
        super().__init__(f"bad detect selection: {what}")


@dataclass(frozen=True)
class Selection:
    """Objects to keep: those of ``colour`` (a palette name)."""

    colour: str


def split_selection(
    payload: bytes, palette: tuple[tuple[str, tuple[int, int, int]], ...] = DEFAULT_PALETTE
) -> tuple[Selection | None, bytes]:
    """(selection, cloud payload) of a detect query's payload.

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
    unknown = sorted(set(data) - set(KNOWN))
    if unknown or not data:
        raise BadSelection(f'expected {{"colour": NAME}}, got keys {sorted(data)}')
    colour = data.get("colour", data.get("color"))
    names = [n for n, _ in palette]
    if colour not in names:
        raise BadSelection(f"colour {colour!r} is not one of {names}")
    return Selection(colour=str(colour)), b""


def select(det: Detection, selection: Selection | None) -> Detection:
    """``det`` with only the selected objects (status ``no_object`` when none is left)."""
    if selection is None:
        return det
    objects = [o for o in det.objects if o.colour == selection.colour]
    status = det.status if det.status == "no_board" else ("ok" if objects else "no_object")
    return det.model_copy(update={"objects": objects, "status": status})
