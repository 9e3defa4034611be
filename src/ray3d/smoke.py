"""A geometry self-check over the bundled Human3.6M cameras (what ``ray3d demo`` runs until the lifting demo
lands): camera height, pitch and roll against the table, and the pixel <-> ray round trip through the lens."""

from __future__ import annotations

import numpy as np

from ray3d import cameras
from ray3d.baselines.rfrh import DEFAULT_ROOT_HEIGHT_M, rfrh_root


def _points_in_capture_volume(n: int = 2000, seed: int = 0) -> np.ndarray:
    """(n, 3) world points where Human3.6M subjects move: a 4 x 4 m floor area, 0-2 m high."""
    rng = np.random.default_rng(seed)
    return rng.uniform([-2.0, -2.0, 0.0], [2.0, 2.0, 2.0], size=(n, 3))


def geometry_report() -> str:
    points = _points_in_capture_volume()
    pelvis = points.copy()
    pelvis[:, 2] = DEFAULT_ROOT_HEIGHT_M
    table = cameras.h36m_table()["extrinsics"]
    lines = [
        "ray3d geometry check: every bundled Human3.6M camera (lens distortion included)",
        f"{'camera':<22}{'height m':>9}{'(table)':>9}{'pitch deg':>10}{'(table)':>9}{'roll deg':>9}"
        f"{'ray err mm':>11}{'RFRH err mm':>12}",
    ]
    worst = 0.0
    for camera in cameras.h36m_all():
        _, subject, camera_id = camera.name.split(":")
        expected = table[subject][camera_id]
        # Back-project each pixel and walk its ray to the true camera depth: that must land on the point.
        depth = camera.world_to_camera(points)[:, 2:3]
        rays = camera.pixels_to_rays(camera.project(points), frame="camera")
        ray_error = np.linalg.norm(camera.camera_to_world(depth * rays) - points, axis=-1).max()
        rfrh_error = np.linalg.norm(rfrh_root(camera.project(pelvis), camera) - pelvis, axis=-1).max()
        worst = max(worst, ray_error, rfrh_error)
        lines.append(
            f"{camera.name:<22}{camera.camera_height:>9.4f}{expected['derived_height_m']:>9.4f}"
            f"{np.degrees(camera.pitch):>10.3f}{expected['derived_pitch_deg']:>9.3f}{np.degrees(camera.roll):>9.2f}"
            f"{ray_error * 1e3:>11.2e}{rfrh_error * 1e3:>12.2e}")
    lines.append(f"largest round-trip error over {len(points)} points per camera: {worst * 1e3:.2e} mm")
    return "\n".join(lines)
