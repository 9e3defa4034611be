"""One training loop for every model: random virtual cameras per sample, validation every epoch on the
validation performers (the best epoch is kept), safetensors checkpoints written atomically, resumable,
deterministic with a seed, and data-parallel over processes with ``torch.distributed`` (torchrun; gloo on
CPU, nccl on GPUs)."""

from __future__ import annotations

import dataclasses
import json
import os
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ray3d.checkpoints import MODEL_PREFIX, TRAINED_PREFIX, prefixed, read_checkpoint, save_checkpoint, unprefixed
from ray3d.console import progress_bar
from ray3d.data.motion import MotionSet, load_shipped
from ray3d.data.samples import Batch, SampleConfig, SampleGenerator
from ray3d.data.virtual_cameras import CameraRanges
from ray3d.errors import InputError
from ray3d.models.network import LiftingNetwork, ModelConfig, lifting_loss, predict_world
from ray3d.models.presets import preset
from ray3d.models.tensor_batch import TensorBatch

DATA_PROVENANCE = ("CMU Graphics Lab Motion Capture Database (mocap.cs.cmu.edu; free for research and commercial "
                   "use, not for resale; created with funding from NSF EIA-0196217) and HDM05 (Mueller et al. 2007, "
                   "CC BY-SA 3.0), training performers only; see LICENSE-DATA.md of the mocap data")


@dataclasses.dataclass
class TrainConfig:
    """Everything a run depends on, saved as ``config.json`` beside its checkpoints. The model's window and
    NCS variant (``model.window``, ``model.remove_roll``) decide how the samples are cut and seen."""

    model: ModelConfig = ModelConfig()
    samples: SampleConfig = SampleConfig()
    epochs: int = 30
    batches_per_epoch: int = 100
    batch_size: int = 1024
    learning_rate: float = 1e-3
    lr_decay: float = 0.95            # per epoch
    seed: int = 0
    validation_samples: int = 4096
    # Validate and ship an exponential moving average of the weights (and batch-norm statistics) with this
    # decay per step, which smooths the epoch-to-epoch swings of the last weights; 0 = the last weights.
    ema_decay: float = 0.0
    data_dir: str | None = None
    datasets: tuple[str, ...] = ("cmu", "hdm05")   # which shipped mocap to train and validate on
    threads: int | None = None
    # Fine-tuning: the weights a run starts from (a checkpoint of the same model; its optimizer state is not
    # taken), relative to the working directory.
    init_from: str | None = None

    def __post_init__(self) -> None:
        # JSON gives lists and dicts where the fields hold tuples and dataclasses.
        self.datasets = tuple(self.datasets)
        if isinstance(self.model, dict):
            self.model = ModelConfig(**self.model)
        if isinstance(self.samples, dict):
            samples = dict(self.samples)
            if isinstance(samples.get("cameras"), dict):
                samples["cameras"] = camera_ranges(samples["cameras"])
            samples["extra_cameras"] = tuple(camera_ranges(r) if isinstance(r, dict) else r
                                             for r in samples.get("extra_cameras", ()))
            self.samples = SampleConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in samples.items()})
        if self.model.output_skeleton.name != "h36m17":
            raise InputError(f"model {self.model.name}: the mocap trains H36M-17 outputs, not "
                             f"{self.model.output_skeleton.name} (set output_layout to h36m17)")

    @classmethod
    def from_dict(cls, document: dict[str, Any]) -> TrainConfig:
        """From a config file's form: ``{"preset": NAME, "model": {overrides}, ...other fields}``, or, without
        a preset, a whole configuration as saved beside a checkpoint."""
        document = dict(document)
        name = document.pop("preset", None)
        if name is not None:
            document["model"] = preset(name, **document.get("model", {}))
        return cls(**document)

    @classmethod
    def from_json(cls, path: str | Path) -> TrainConfig:
        try:
            return cls.from_dict(config_document(path))
        except InputError:
            raise
        except (OSError, json.JSONDecodeError, TypeError, KeyError, ValueError) as err:
            raise InputError(f"{path}: not a training config ({err})") from None

    def to_dict(self) -> dict[str, Any]:
        return json.loads(json.dumps(dataclasses.asdict(self)))


def camera_ranges(document: dict[str, Any]) -> CameraRanges:
    """Camera ranges from a config's form (lists where the fields hold tuples)."""
    return CameraRanges(**{k: tuple(v) if isinstance(v, list) else v for k, v in document.items()})


def config_document(path: str | Path, _seen: tuple[Path, ...] = ()) -> dict[str, Any]:
    """A config file's document, over the document of the config it names as ``base`` (a file beside it): a
    config lists only what it changes from its base, and nested fields (``model``, ``samples``) merge."""
    path = Path(path)
    if path.resolve() in _seen:
        raise InputError(f"{path}: its bases name it again ({' -> '.join(p.name for p in _seen)})")
    document = json.loads(path.read_text())
    base = document.pop("base", None)
    if base is None:
        return document
    return _merged(config_document(path.parent / base, (*_seen, path.resolve())), document)


def _merged(base: dict, changes: dict) -> dict:
    merged = dict(base)
    for key, value in changes.items():
        both = isinstance(value, dict) and isinstance(merged.get(key), dict)
        merged[key] = _merged(merged[key], value) if both else value
    return merged


def _distributed() -> tuple[int, int]:
    """(rank, world size), starting the process group when launched by torchrun."""
    world = int(os.environ.get("WORLD_SIZE", "1"))
    if world > 1 and not torch.distributed.is_initialized():
        torch.distributed.init_process_group("nccl" if torch.cuda.is_available() else "gloo")
    return (torch.distributed.get_rank(), world) if world > 1 else (0, 1)


def training_config(path: str | Path | None = None, model_preset: str | None = None, **overrides: Any) -> TrainConfig:
    """The configuration of a run: the file at ``path`` (default: every default, the ``ray3d`` lite model), its
    model replaced by ``model_preset`` when given, then the fields in ``overrides`` (None values ignored)."""
    config = TrainConfig.from_json(path) if path else TrainConfig()
    if model_preset:
        config = dataclasses.replace(config, model=preset(model_preset))
    return dataclasses.replace(config, **{k: v for k, v in overrides.items() if v is not None})


def sample_generator(config: TrainConfig, split: str, samples: SampleConfig, seed: int,
                     motion: MotionSet | None = None) -> SampleGenerator:
    """Samples of ``split``'s performers (``motion``, when already loaded) cut and seen the way
    ``config.model`` reads them."""
    motion = motion if motion is not None else load_shipped(config.data_dir, split, config.datasets)
    return SampleGenerator(motion, samples, config.model.window, config.model.remove_roll, seed=seed,
                           layout=config.model.layout)


def validation_batch(config: TrainConfig) -> Batch:
    """A fixed batch from the validation performers: same windows and cameras for every epoch and run."""
    clean = dataclasses.replace(config.samples, flip_probability=0.0, noise_px=0.0, drop_probability=0.0,
                                bone_scale=(1.0, 1.0), bone_jitter=0.0)
    return sample_generator(config, "validation", clean, 10_000 + config.seed).batch(config.validation_samples)


def batch_tensors(batch: Batch, device: str | torch.device = "cpu") -> TensorBatch:
    """A training batch as the network's input."""
    return TensorBatch.from_arrays(batch.pixels, batch.rays, batch.cameras, device, batch.confidences)


@torch.no_grad()
def world_errors_mm(model: LiftingNetwork, batch: Batch, device: torch.device, chunk: int = 4096) -> dict[str, float]:
    """Mean Abs-MPJPE, MPJPE and MRPE (mm) of ``model`` on a batch, in the world frame."""
    from ray3d import metrics

    model.eval()
    predictions = []
    for start in range(0, len(batch.root), chunk):
        part = batch.take(slice(start, start + chunk))
        predictions.append(predict_world(model, batch_tensors(part, device), part.cameras).cpu().numpy())
    predicted = np.concatenate(predictions)
    target = batch.world.astype(np.float64)
    return {"abs_mpjpe_mm": 1e3 * float(metrics.abs_mpjpe(predicted, target)),
            "mpjpe_mm": 1e3 * float(metrics.mpjpe(predicted, target)),
            "mrpe_mm": 1e3 * float(metrics.mrpe(predicted, target))}



def _warming_ema(decay: float):
    """An exponential moving average whose decay grows from 0.1 to ``decay`` over the first steps, so the
    average forgets the random initial weights as fast as the weights leave them."""
    def average(averaged: torch.Tensor, current: torch.Tensor, steps: torch.Tensor) -> torch.Tensor:
        if not current.is_floating_point():
            # Integer buffers (the joint groups' index tensors, batch counts) are copied: averaged in floating
            # point and written back they are truncated (15 became 14), which broke the averaged model.
            return current
        rate = min(decay, (1 + int(steps)) / (10 + int(steps)))
        return rate * averaged + (1 - rate) * current

    return average


def _optimizer_tensors(optimizer: torch.optim.Optimizer) -> tuple[dict[str, torch.Tensor], list[dict]]:
    state = optimizer.state_dict()
    tensors = {f"optimizer.{index}.{name}": (value if torch.is_tensor(value) else torch.tensor(value))
               for index, entries in state["state"].items() for name, value in entries.items()}
    return tensors, state["param_groups"]


def _load_optimizer(optimizer: torch.optim.Optimizer, tensors: dict[str, torch.Tensor], groups: list[dict]) -> None:
    state: dict[int, dict[str, torch.Tensor]] = {}
    for key, value in tensors.items():
        if key.startswith("optimizer."):
            _, index, name = key.split(".", 2)
            state.setdefault(int(index), {})[name] = value
    optimizer.load_state_dict({"state": state, "param_groups": groups})


def make_optimizer(model: torch.nn.Module, config: TrainConfig) -> torch.optim.Optimizer:
    """Adam with AMSGrad, as the paper; fused into one kernel per step (fewer passes over the weights)."""
    return torch.optim.Adam(model.parameters(), lr=config.learning_rate, amsgrad=True, fused=True)


def training_step(trained: torch.nn.Module, model: LiftingNetwork, optimizer: torch.optim.Optimizer,
                  generator: SampleGenerator, batch_size: int, device: torch.device,
                  share: slice = slice(None)) -> np.ndarray:
    """One optimisation step of ``trained`` (``model``, or its data-parallel wrapper) on this process's
    ``share`` of a batch drawn from ``generator``; returns [loss, pose error (m), root error (relative)]."""
    batch = generator.batch(batch_size).take(share)
    tensors = batch_tensors(batch, device)
    target_pose, target_root = model.targets(tensors, torch.from_numpy(batch.pose).to(device),
                                             torch.from_numpy(batch.root).to(device))
    pose, root = trained(tensors)
    loss, pose_error, root_error = lifting_loss(pose, root, target_pose, target_root)
    optimizer.zero_grad(set_to_none=True)
    loss.backward()
    optimizer.step()
    return np.array([loss.item(), pose_error.item(), root_error.item()])


def training_steps(config: TrainConfig, motion: MotionSet | None = None) -> Iterator[np.ndarray]:
    """``train``'s steps on one process from freshly initialised weights, without end, validation or
    checkpoints: what ``ray3d bench speed`` times as the training loop's rate. ``motion``: the training
    performers' mocap, when already loaded."""
    torch.manual_seed(config.seed)
    model = LiftingNetwork(config.model).train()
    optimizer = make_optimizer(model, config)
    generator = sample_generator(config, "train", config.samples, config.seed, motion)
    while True:
        yield training_step(model, model, optimizer, generator, config.batch_size, torch.device("cpu"))


def train(config: TrainConfig, out: str | Path, resume: bool = False, progress: bool = True) -> dict[str, Any]:
    """Train, writing ``out/best.*`` (best validation epoch) and ``out/last.*`` (to resume).

    Returns {"epoch", "best", "history"}; on data-parallel ranks other than 0, "best" is None and the history
    empty (rank 0 alone validates and writes).
    """
    out = Path(out)
    rank, world = _distributed()
    if config.threads:
        torch.set_num_threads(config.threads)
    if (out / "last.json").exists() and not resume:
        raise InputError(f"{out}: holds a run already; resume it or choose another output folder",
                         arguments=("resume", "out"))
    if config.batch_size % world:
        raise InputError(f"batch size {config.batch_size} does not split over {world} processes")
    device = torch.device(f"cuda:{rank % torch.cuda.device_count()}" if torch.cuda.is_available() else "cpu")
    torch.manual_seed(config.seed)
    model = LiftingNetwork(config.model).to(device)
    if config.init_from:
        model.load_state_dict(unprefixed(read_checkpoint(config.init_from)[0], MODEL_PREFIX))
    optimizer = make_optimizer(model, config)
    ema = None if not config.ema_decay else torch.optim.swa_utils.AveragedModel(
        model, avg_fn=_warming_ema(config.ema_decay), use_buffers=True)
    shipped = model if ema is None else ema.module  # the weights validated and written as "model."
    # Every process draws the same whole batch and trains on its share: N processes with batch B train exactly as
    # one process with batch N x B (the batch norms see the whole batch too).
    generator = sample_generator(config, "train", config.samples, config.seed)
    state = {"epoch": 0, "best": None, "history": [], "train_seconds": 0.0}
    if resume and (out / "last.json").exists():
        tensors, document = read_checkpoint(out / "last.safetensors")
        model.load_state_dict(unprefixed(tensors, MODEL_PREFIX if ema is None else TRAINED_PREFIX))
        if ema is not None:
            ema.module.load_state_dict(unprefixed(tensors, MODEL_PREFIX))
            ema.n_averaged.fill_(int(tensors["ema_steps"]))
        _load_optimizer(optimizer, tensors, document["optimizer_param_groups"])
        state = {k: document.get(k, 0.0) for k in ("epoch", "best", "history", "train_seconds")}
        generator.rng.bit_generator.state = document["generator_state"]["0"]
        torch.set_rng_state(tensors["torch_rng_state"])
    if rank == 0:
        out.mkdir(parents=True, exist_ok=True)
        (out / "config.json").write_text(json.dumps(config.to_dict(), indent=1))
    trained = torch.nn.parallel.DistributedDataParallel(model) if world > 1 else model
    validation = validation_batch(config) if rank == 0 else None
    local_batch = config.batch_size // world

    for epoch in range(state["epoch"], config.epochs):
        for group in optimizer.param_groups:
            group["lr"] = config.learning_rate * config.lr_decay ** epoch
        model.train()
        started, totals = time.perf_counter(), np.zeros(3)
        bar = progress_bar(range(config.batches_per_epoch), shown=progress and rank == 0,
                           desc=f"epoch {epoch + 1}/{config.epochs}", leave=False)
        for step in bar:
            totals += training_step(trained, model, optimizer, generator, config.batch_size, device,
                                    slice(rank * local_batch, (rank + 1) * local_batch))
            if ema is not None:
                ema.update_parameters(model)
            rate = (step + 1) * config.batch_size / (time.perf_counter() - started)
            bar.set_postfix(loss=f"{totals[0] / (step + 1):.4f}", samples_s=f"{rate:,.0f}")
        state["train_seconds"] += time.perf_counter() - started
        if rank == 0:
            record = {"epoch": epoch + 1, "loss": totals[0] / config.batches_per_epoch,
                      "train_pose_m": totals[1] / config.batches_per_epoch,
                      "train_root_rel": totals[2] / config.batches_per_epoch,
                      "samples_per_s": config.batches_per_epoch * config.batch_size / (time.perf_counter() - started),
                      "lr": optimizer.param_groups[0]["lr"], **world_errors_mm(shipped, validation, device)}
            state["history"].append(record)
            state["epoch"] = epoch + 1
            if progress:
                print(f"epoch {epoch + 1}: loss {record['loss']:.4f}  "
                      f"validation Abs-MPJPE {record['abs_mpjpe_mm']:.1f} "
                      f"MPJPE {record['mpjpe_mm']:.1f} MRPE {record['mrpe_mm']:.1f} mm  "
                      f"({record['samples_per_s']:,.0f} samples/s)", flush=True)
            weights = prefixed(shipped.state_dict(), MODEL_PREFIX)
            training_state = {} if ema is None else {**prefixed(model.state_dict(), TRAINED_PREFIX),
                                                      "ema_steps": ema.n_averaged.detach().clone()}
            provenance = {"model": config.model, "train_config": config.to_dict(), "trained_on": DATA_PROVENANCE}
            if state["best"] is None or record["abs_mpjpe_mm"] < state["best"]["abs_mpjpe_mm"]:
                state["best"] = record
                save_checkpoint(out / "best.safetensors", weights, {**provenance, "epoch": epoch + 1,
                                                                     "validation": record})
            optimizer_tensors, groups = _optimizer_tensors(optimizer)
            save_checkpoint(out / "last.safetensors", {**weights, **training_state, **optimizer_tensors,
                                                       "torch_rng_state": torch.get_rng_state()},
                            {**provenance, **state, "optimizer_param_groups": groups,
                             "generator_state": {str(rank): generator.rng.bit_generator.state}})
    if world > 1:
        torch.distributed.barrier()
        torch.distributed.destroy_process_group()
    return state
