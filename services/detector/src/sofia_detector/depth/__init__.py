"""Stage 2, depth cleaning: the pixels standing above the board, without flying pixels, joined across
holes of their colour (:func:`raised_pixels`)."""

from .clean import Raised, raised_pixels

__all__ = ["Raised", "raised_pixels"]
