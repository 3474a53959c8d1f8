"""Pixel grids, point frames and rectangles: the building blocks every stage uses."""
