"""Stage 4, one object from its points: footprint, height, centre, visibility and colour
(:mod:`.footprint`, :mod:`.visibility`, :mod:`.colour`)."""
