"""ray3d: absolute 3D human poses in metres in the world frame from 2D keypoints seen by one calibrated camera.

The names below are imported when first used (PEP 562), so a command or a worker process that needs only part
of the package does not pay for the rest (``calibrate`` alone brings OpenCV and scipy.optimize).
"""

import importlib
from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("ray3d")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.0.0+unknown"

_MODULES = ("calibrate", "cameras", "metrics", "skeleton")
_NAMES = {"Camera": "ray3d.geometry", "InputError": "ray3d.errors", "Lifter": "ray3d.lifting.lifter",
          "read_camera": "ray3d.io.camera_files", "read_world": "ray3d.io.world"}

__all__ = sorted([*_NAMES, *_MODULES, "__version__"])


def __getattr__(name: str):
    if name in _MODULES:
        return importlib.import_module(f"ray3d.{name}")
    if name in _NAMES:
        return getattr(importlib.import_module(_NAMES[name]), name)
    raise AttributeError(f"module 'ray3d' has no attribute {name!r}")


def __dir__() -> list[str]:
    return __all__
