"""Camera geometry: the camera model, lens distortion, world / camera / normalized frames, pixels <-> rays."""

from ray3d.geometry.camera import Camera
from ray3d.geometry.transforms import (
    camera_center,
    camera_pitch,
    camera_roll,
    camera_to_normalized,
    camera_to_pixels,
    camera_to_world,
    normalized_to_camera,
    pixels_to_camera_rays,
    rays_camera_to_normalized,
    rays_normalized_to_camera,
    rotation_from_angles,
    world_to_camera,
)

__all__ = [
    "Camera", "camera_center", "camera_pitch", "camera_roll", "camera_to_normalized", "camera_to_pixels",
    "camera_to_world", "normalized_to_camera", "pixels_to_camera_rays", "rays_camera_to_normalized", "rays_normalized_to_camera",
    "rotation_from_angles",
    "world_to_camera",
]
