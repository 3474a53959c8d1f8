"""The numba compiler as the detector uses it, for the few loops numpy cannot do in one pass.

Kernels are compiled for C-contiguous arrays, cached beside the sources (``cache=True``;
``~/.cache/numba`` when that is read-only) and compiled ahead of the first detection
(:func:`sofia_detector.warmup.compile_kernels`). Each kernel's docstring gives its measured time
against the numpy form it replaces (``bench/bench_detector_kernels.py``).
"""

from __future__ import annotations

import numba

jit = numba.njit(cache=True, nogil=True, error_model="numpy")
