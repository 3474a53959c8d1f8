"""The fit: samples in, ``T_flange_cam`` with its camera correction, noise and diagnostics out
(:func:`.calibrate.calibrate`); compiled building blocks at the bottom (``kernels``, ``so3``)."""
