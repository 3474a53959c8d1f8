"""Stage 4, one object from its points: footprint, height, centre, visibility and colour
(:func:`estimate_object`, :func:`in_view`, :func:`object_colour`)."""
