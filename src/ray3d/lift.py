"""``Lifter``: users' 2D keypoints and camera -> 3D joints in metres in the world frame."""

from __future__ import annotations

import dataclasses

import numpy as np
import torch

from ray3d.checkpoints import load_model
from ray3d.data.samples import window_indices
from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.geometry.arrays import check_points
from ray3d.models.network import LiftingNetwork, TensorBatch, frame_to_world
from ray3d.data.virtual_cameras import CameraBatch
from ray3d.skeleton import convert


@dataclasses.dataclass
class LiftResult:
    """World joints (T, 17, 3) in metres (z up, floor z = 0) and the root trajectory (T, 3)."""

    joints: np.ndarray
    root: np.ndarray


class Lifter:
    """A trained network ready to lift. ``Lifter.load()`` gives the shipped Ray3D weights."""

    def __init__(self, model: LiftingNetwork, document: dict):
        self.model, self.document = model.eval(), document

    @classmethod
    def load(cls, name_or_path: str = "ray3d") -> Lifter:
        return cls(*load_model(name_or_path))

    @property
    def receptive_field(self) -> int:
        return self.model.receptive_field

    @torch.no_grad()
    def lift(self, keypoints: np.ndarray, camera: Camera, layout: str = "h36m17", flip_test: bool = False,
             chunk: int = 8192) -> LiftResult:
        """Lift (T, J, 2) pixel keypoints of one person seen by ``camera`` to world joints."""
        pixels = check_points(keypoints, 2, "keypoints")
        if pixels.ndim != 3:
            raise InputError(f"keypoints: expected (frames, joints, 2), got {tuple(pixels.shape)}")
        pixels = np.asarray(convert(np.asarray(pixels, dtype=np.float64), layout, "h36m17"))
        rays = camera.pixels_to_rays(pixels)
        if not np.isfinite(rays).all():
            raise InputError("keypoints: some lie where the camera's lens model cannot be inverted")
        frames, count = self.receptive_field, len(pixels)
        centres = np.arange(count)
        index = window_indices(centres, np.zeros_like(centres), np.full_like(centres, count - 1), frames)
        cams = CameraBatch.from_cameras([camera])
        joints = []
        for start in range(0, count, chunk):
            part = index[start:start + chunk]
            n = len(part)
            batch_cams = dataclasses.replace(cams, **{f: np.repeat(getattr(cams, f), n, axis=0)
                                                      for f in ("R", "t", "intrinsics", "dist", "height", "pitch")})
            tensors = TensorBatch(torch.as_tensor(pixels[part], dtype=torch.float32),
                                  torch.as_tensor(rays[part], dtype=torch.float32),
                                  torch.as_tensor(np.stack([batch_cams.height, batch_cams.pitch], -1), dtype=torch.float32),
                                  torch.as_tensor(batch_cams.intrinsics, dtype=torch.float32), float(camera.image_size[0]))
            pose, root = self.model.predict(tensors, flip_test)
            world = frame_to_world(pose + root[:, None], self.model.config.output_frame, batch_cams,
                                   tensors.camera_params)
            joints.append(world.numpy().astype(np.float64))
        world_joints = np.concatenate(joints)
        return LiftResult(world_joints, world_joints[:, 0])
