"""Stage 2, depth cleaning: flying pixels, pixel spacing, holes bridged by colour."""
