"""Named model configurations: Ray3D (``lite`` and ``paper`` sizes), its ablations and the baselines.

Sizes: ``lite`` trains on 2 CPU cores in about an hour; ``paper`` is the reference implementation's size
(46 M parameters, ~96 MFLOPs per frame for pose and trajectory networks together; the reference has ~46 M and
~92 MFLOPs): 1024 hidden units as the reference, and 640 conv channels because our per-group encoders and fusion
are laid out differently from its 256-channel ones. The learned baselines use the lite budget so comparisons are
like for like.
"""

from __future__ import annotations

import dataclasses

from ray3d.errors import InputError
from ray3d.models.network import ModelConfig

_LITE = dict(channels=128, hidden=256, kernels=(3, 3), dropout=0.1)
_PAPER = dict(channels=640, hidden=1024, kernels=(3, 3), dropout=0.2, fusion=True)
_BASELINE = dict(camera_embedding=False, output_frame="camera", root="xyz", ground_features=False)

PRESETS: dict[str, ModelConfig] = {
    # Ours: Ray3D with the root as a depth along its ray and the ground-plane features.
    "ray3d": ModelConfig(name="ray3d", **_LITE),
    "ray3d-paper": ModelConfig(name="ray3d-paper", **_PAPER),
    # Live use: the window is the present frame and the 8 before it.
    "ray3d-causal": ModelConfig(name="ray3d-causal", causal=True, **_LITE),
    # The paper's Ray3D exactly: root regressed as NCS xyz, no ground features.
    "ray3d-xyz": ModelConfig(name="ray3d-xyz", root="xyz", ground_features=False, **_LITE),
    # Ablations: no camera embedding; intrinsic decoupling only (camera-frame rays, no NCS).
    "ray3d-no-ce": ModelConfig(name="ray3d-no-ce", camera_embedding=False, root="xyz", ground_features=False,
                               **_LITE),
    "rie-decoupled": ModelConfig(name="rie-decoupled", input="camera_rays", **_BASELINE, **_LITE),
    # Baselines on pixels.
    "rie": ModelConfig(name="rie", input="pixels", **_BASELINE, **_LITE),
    "videopose3d": ModelConfig(name="videopose3d", input="pixels", backbone="tcn",
                               **{**_BASELINE, **_LITE, "channels": 256}),
    "poselifter": ModelConfig(name="poselifter", input="pixels_centred", backbone="mlp",
                              **{**_BASELINE, **_LITE, "kernels": (1,), "root": "focal_depth", "hidden": 512}),
    # PoseFormer-style: attention over each frame's joints, then over the 9 frames; 8 features per joint (the
    # paper's 32 and 4 + 4 blocks train at a tenth of the lite models' rate on 2 CPU cores).
    "poseformer": ModelConfig(name="poseformer", input="pixels", backbone="transformer",
                              **{**_BASELINE, **_LITE, "kernels": (9,), "channels": 8, "layers": 2}),
}


def preset(preset_name: str, /, **overrides) -> ModelConfig:
    """The named configuration with ``overrides`` (``name`` among them renames the model)."""
    if preset_name not in PRESETS:
        raise InputError(f"unknown model preset {preset_name!r}; known: {', '.join(PRESETS)}")
    return dataclasses.replace(PRESETS[preset_name], **overrides)
