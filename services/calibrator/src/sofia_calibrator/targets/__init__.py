"""Calibration targets other than the blob: each turns one view into camera-frame points with
their uncertainty, for :func:`sofia_calibrator.calibrate`."""

from .files import read_cloud, read_euler_poses
from .sphere import Sphere, SphereNotFound, find_sphere, sphere_centres

__all__ = ["Sphere", "SphereNotFound", "find_sphere", "read_cloud", "read_euler_poses", "sphere_centres"]
