"""The fit: samples in, ``T_flange_cam`` with its camera correction, noise and diagnostics out.

Layers, from the bottom: ``kernels`` (compiled linear algebra), ``so3``; ``noise``, ``correction``,
``fit_kernels``; ``solver``, ``diagnostics``; ``influence``, ``screen``, ``simulate``; ``fit``;
``advice``; ``calibrate`` (the entry point); ``warm`` (compiles the kernels ahead).
"""
