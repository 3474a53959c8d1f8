"""Calibration targets other than the blob: each turns one view into camera-frame points with
their uncertainty, for :func:`sofia_calibrator.calibrate`."""

from .ball import Ball, find_ball
from .files import read_cloud, read_euler_poses
from .sphere import Sphere, SphereNotFound, find_sphere
from .sphere_shared import shared_spheres, sphere_centres

__all__ = [
    "Ball",
    "Sphere",
    "SphereNotFound",
    "find_ball",
    "find_sphere",
    "read_cloud",
    "read_euler_poses",
    "shared_spheres",
    "sphere_centres",
]
