"""The numba compiler as the detector uses it: C-contiguous arrays, cached beside the sources
(``~/.cache/numba`` when read-only), compiled before the first detection (:mod:`..warmup`). Each
kernel's docstring gives its time against its numpy form (``bench/bench_detector_kernels.py``)."""

from __future__ import annotations

import numba

jit = numba.njit(cache=True, nogil=True, error_model="numpy")
