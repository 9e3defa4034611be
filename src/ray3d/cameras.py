"""Named camera tables shipped with the package: the Human3.6M calibrations.

The table (``assets/h36m_cameras.json``) holds public calibration facts: intrinsics per camera id (shared by
all subjects) and world->camera extrinsics per subject, in a z-up world with the floor at z = 0, metres.
"""

from __future__ import annotations

import functools
import json
from importlib import resources

from ray3d.errors import InputError
from ray3d.geometry.camera import Camera

H36M_CAMERA_IDS = ("54138969", "55011271", "58860488", "60457274")


@functools.cache
def h36m_table() -> dict:
    """The raw Human3.6M calibration table (intrinsics, extrinsics, derived height and pitch)."""
    return json.loads(resources.files("ray3d.assets").joinpath("h36m_cameras.json").read_text())


def h36m_subjects() -> list[str]:
    """Subjects with extrinsics, e.g. ['S1', 'S5', ...]."""
    return sorted(h36m_table()["extrinsics"], key=lambda s: int(s[1:]))


def h36m(subject: str, camera_id: str | int) -> Camera:
    """The Human3.6M camera ``camera_id`` of ``subject``, distortion included, named ``h36m:S1:54138969``."""
    table = h36m_table()
    camera_id = str(camera_id)
    if subject not in table["extrinsics"]:
        raise InputError(f"h36m camera: unknown subject {subject!r}; known: {', '.join(h36m_subjects())} "
                         "(S2, S3, S4 have no extrinsics)")
    if camera_id not in table["intrinsics"]:
        raise InputError(f"h36m camera: unknown camera id {camera_id!r}; known: {', '.join(H36M_CAMERA_IDS)}")
    intrinsics, extrinsics = table["intrinsics"][camera_id], table["extrinsics"][subject][camera_id]
    return Camera.from_intrinsics(
        intrinsics["fx"], intrinsics["fy"], intrinsics["cx"], intrinsics["cy"], intrinsics["dist_opencv"],
        extrinsics["R"], extrinsics["t"], (intrinsics["width"], intrinsics["height"]),
        name=f"h36m:{subject}:{camera_id}")


def h36m_all() -> list[Camera]:
    """Every Human3.6M camera with extrinsics (subjects x 4 cameras)."""
    return [h36m(subject, camera_id) for subject in h36m_subjects() for camera_id in H36M_CAMERA_IDS
            if camera_id in h36m_table()["extrinsics"][subject]]
