"""Networks: the RIE backbone, camera embedding, Ray3D and the learned baselines, presets, checkpoints."""

from ray3d.models.network import LiftingNetwork, ModelConfig
from ray3d.models.presets import PRESETS, preset
from ray3d.models.tensor_batch import TensorBatch

__all__ = ["LiftingNetwork", "ModelConfig", "PRESETS", "TensorBatch", "preset"]
