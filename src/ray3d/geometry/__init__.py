"""Camera geometry: the camera model, lens distortion, world / camera / normalized frames, pixels <-> rays,
camera placement and batches of cameras."""

from ray3d.geometry.camera import Camera
from ray3d.geometry.camera_batch import CameraBatch
from ray3d.geometry.intrinsics import focal_from_hfov, parse_image_size, pinhole_intrinsics
from ray3d.geometry.transforms import (
    camera_center,
    camera_pitch,
    camera_roll,
    camera_to_normalized,
    camera_to_pixels,
    camera_to_world,
    centre_looking_at,
    forward_direction,
    normalized_to_camera,
    pixels_to_camera_rays,
    rays_camera_to_normalized,
    rays_normalized_to_camera,
    rotation_from_angles,
    world_to_camera,
    y_up_to_z_up,
)

__all__ = [
    "Camera", "CameraBatch", "camera_center", "camera_pitch", "camera_roll", "camera_to_normalized",
    "camera_to_pixels", "camera_to_world", "centre_looking_at", "focal_from_hfov", "forward_direction",
    "normalized_to_camera", "parse_image_size", "pinhole_intrinsics", "pixels_to_camera_rays",
    "rays_camera_to_normalized", "rays_normalized_to_camera", "rotation_from_angles", "world_to_camera", "y_up_to_z_up",
]
