"""The moving average against the last trained weights of a run with ``ema_decay``: both halves of
``RUN/last.safetensors`` reloaded and scored on the run's validation batch (world Abs-MPJPE, MPJPE, MRPE, mm).

    python benchmarks/ema_check.py RUN_DIR
"""

from __future__ import annotations

import json
import sys

import torch

from ray3d.checkpoints import MODEL_PREFIX, TRAINED_PREFIX, read_checkpoint, unprefixed
from ray3d.models.network import LiftingNetwork
from ray3d.train import TrainConfig, validation_batch, world_errors_mm


def main() -> None:
    run = sys.argv[1]
    config = TrainConfig.from_dict(json.load(open(f"{run}/config.json")))
    tensors, _ = read_checkpoint(f"{run}/last.safetensors")
    validation = validation_batch(config)
    for label, prefix in (("average", MODEL_PREFIX), ("last weights", TRAINED_PREFIX)):
        model = LiftingNetwork(config.model)
        model.load_state_dict(unprefixed(tensors, prefix))
        print(label, {k: round(v, 1) for k, v in world_errors_mm(model, validation, torch.device("cpu")).items()})


if __name__ == "__main__":
    main()
