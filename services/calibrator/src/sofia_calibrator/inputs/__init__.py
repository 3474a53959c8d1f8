"""Sample files read by ``sofia calibrate``: the lab's pair, CSV/JSON/joint files, MCAP recordings."""
