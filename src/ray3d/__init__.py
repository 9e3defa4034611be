"""ray3d: absolute 3D human poses in metres in the world frame from 2D keypoints seen by one calibrated camera."""

from importlib.metadata import PackageNotFoundError, version

from ray3d import calibrate, cameras, metrics, skeleton
from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.io.camera_files import read_camera
from ray3d.io.world import read_world
from ray3d.lift import Lifter

try:
    __version__ = version("ray3d")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.0.0+unknown"

__all__ = ["Camera", "InputError", "Lifter", "calibrate", "cameras", "metrics", "read_camera", "read_world", "skeleton",
           "__version__"]
