"""Stage 4, one object from its points: footprint, height, centre, visibility and colour, as a
message (:func:`measure_objects`; :mod:`.footprint`, :mod:`.visibility`, :mod:`.colour`)."""

from .measure import measure_objects

__all__ = ["measure_objects"]
