"""``TensorBatch``: what a network reads, as torch tensors: the windows' pixels, NCS rays and confidences, and the
cameras' parameters."""

from __future__ import annotations

import dataclasses

import numpy as np
import torch

from ray3d.geometry import CameraBatch
from ray3d.skeleton import Skeleton, flip, mirror_pixels


@dataclasses.dataclass
class TensorBatch:
    """A batch as torch tensors: pixels (B, F, J, 2), rays (B, F, J, 3) in the NCS, camera_params (B, 2),
    intrinsics (B, 4), roll (B,) (used only by gravity-aligned models), image width (pixels are normalised by it),
    confidences (B, F, J) of the detector in [0, 1] (read only by models with ``confidence_input``; default:
    every joint fully seen)."""

    pixels: torch.Tensor
    rays: torch.Tensor
    camera_params: torch.Tensor
    intrinsics: torch.Tensor
    roll: torch.Tensor
    image_width: float
    confidences: torch.Tensor | None = None

    def __post_init__(self) -> None:
        if self.confidences is None:
            self.confidences = torch.ones_like(self.rays[..., 0])

    @classmethod
    def from_arrays(cls, pixels: np.ndarray, rays: np.ndarray, cameras: CameraBatch,
                    device: str | torch.device = "cpu", confidences: np.ndarray | None = None) -> TensorBatch:
        """From (B, F, J, 2) pixels, (B, F, J, 3) NCS rays, the B cameras that saw them and optional (B, F, J)
        confidences."""
        def tensor(array: np.ndarray) -> torch.Tensor:
            return torch.from_numpy(np.ascontiguousarray(array, dtype=np.float32)).to(device)

        return cls(tensor(pixels), tensor(rays), tensor(cameras.height_pitch), tensor(cameras.intrinsics),
                   tensor(cameras.roll), float(cameras.image_size[0]),
                   None if confidences is None else tensor(confidences))

    @classmethod
    def example(cls, model_frames: int, joints: int, size: int, seed: int = 0,
                image_width: float = 1000.0) -> TensorBatch:
        """A plausible random batch (rays in front of a 1.5 m high camera, confidences in [0, 1]), for sizing,
        timing and tracing networks."""
        generator = torch.Generator().manual_seed(seed)
        rays = torch.randn(size, model_frames, joints, 3, generator=generator) * 0.2 + torch.tensor([0.0, 0.3, 1.0])
        pixels = torch.rand(size, model_frames, joints, 2, generator=generator) * image_width
        return cls(pixels, rays, torch.tensor([[1.5, 0.2]]).repeat(size, 1),
                   torch.tensor([[1000.0, 1000, 500, 500]]).repeat(size, 1), torch.zeros(size), image_width,
                   torch.rand(size, model_frames, joints, generator=generator))

    def flipped(self, skeleton: Skeleton) -> TensorBatch:
        """The input of the mirrored scene: rays mirrored in the NCS, pixels about the principal point."""
        return dataclasses.replace(self, pixels=mirror_pixels(self.pixels, self.intrinsics[:, None, None, 2], skeleton),
                                   rays=flip(self.rays, skeleton),
                                   confidences=self.confidences[..., list(skeleton.flip_permutation)])
