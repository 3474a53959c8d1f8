"""Stage 3, segmentation: the points of each object (:func:`find_objects`)."""

from .find import find_objects
from .points import ObjectPoints

__all__ = ["ObjectPoints", "find_objects"]
