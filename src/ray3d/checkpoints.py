"""Checkpoints: weights as safetensors beside a JSON document (the configs that built them, and provenance).
Nothing is ever unpickled."""

from __future__ import annotations

import dataclasses
import json
from importlib import resources
from pathlib import Path
from typing import Any

import torch
from safetensors.torch import load_file, save_file

from ray3d.errors import InputError, reads_file
from ray3d.io.atomic import atomic_path, refuse_existing
from ray3d.models.network import LiftingNetwork, ModelConfig
from ray3d.refine.config import model_uncertainty

SHIPPED_DIR = "assets/models"
RFRH = "rfrh"
# Names in a checkpoint: the weights that ship and lift ("model."), and in the last checkpoint of a run that
# kept a moving average, the weights as trained ("raw.").
MODEL_PREFIX, TRAINED_PREFIX = "model.", "raw."


def prefixed(weights: dict[str, torch.Tensor], prefix: str) -> dict[str, torch.Tensor]:
    """A module's ``state_dict`` under ``prefix``, as a checkpoint stores it."""
    return {f"{prefix}{k}": v for k, v in weights.items()}


def unprefixed(tensors: dict[str, torch.Tensor], prefix: str = MODEL_PREFIX) -> dict[str, torch.Tensor]:
    """The tensors stored under ``prefix``, with it removed (a ``state_dict``)."""
    return {k.removeprefix(prefix): v for k, v in tensors.items() if k.startswith(prefix)}


def save_checkpoint(path: str | Path, tensors: dict[str, torch.Tensor], document: dict[str, Any]) -> None:
    """Write ``path`` (.safetensors) and its .json atomically, replacing earlier versions."""
    path = Path(path)
    with atomic_path(path, overwrite=True) as temporary:
        save_file({k: v.detach().contiguous().cpu() for k, v in tensors.items()}, str(temporary))
    with atomic_path(path.with_suffix(".json"), overwrite=True) as temporary:
        temporary.write_text(json.dumps(document, indent=1, default=_json_default))


def _json_default(value: Any) -> Any:
    if dataclasses.is_dataclass(value):
        return dataclasses.asdict(value)
    if isinstance(value, tuple):
        return list(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


@reads_file("checkpoint")
def read_checkpoint(path: str | Path) -> tuple[dict[str, torch.Tensor], dict[str, Any]]:
    path = Path(path)
    if path.suffix != ".safetensors":
        path = path.with_suffix(".safetensors")
    meta = path.with_suffix(".json")
    if not path.is_file() or not meta.is_file():
        raise InputError(f"{path}: a checkpoint is a .safetensors file with its .json beside it; not found")
    try:
        tensors = load_file(str(path))
    except Exception as err:  # safetensors raises its own error types for corrupt files
        raise InputError(f"{path}: not a valid safetensors file ({err})") from None
    try:
        document = json.loads(meta.read_text())
    except json.JSONDecodeError as err:
        raise InputError(f"{meta}: not valid JSON ({err.msg})") from None
    return tensors, document


def model_config(document: dict[str, Any]) -> ModelConfig:
    """A checkpoint document's ``model`` as a ``ModelConfig``: an object of known fields whose network can be
    built, or one ``InputError`` naming the field."""
    fields = document.get("model") if isinstance(document, dict) else None
    if fields is None:
        raise InputError("checkpoint JSON has no 'model' configuration")
    if not isinstance(fields, dict):
        raise InputError(f"checkpoint JSON: model: expected an object of model fields, got {type(fields).__name__}")
    known = {f.name: f.type for f in dataclasses.fields(ModelConfig)}
    unknown = sorted(set(fields) - set(known))
    if unknown:
        raise InputError(f"checkpoint JSON: model: unknown field {unknown[0]!r}; the fields are "
                         f"{', '.join(sorted(known))}")
    for name, value in fields.items():
        if not _of_type(value, known[name]):
            raise InputError(f"checkpoint JSON: model: {name}: expected {known[name]}, got {value!r:.40}")
    try:
        config = ModelConfig(**fields)
        LiftingNetwork(config)
    except InputError as err:
        raise InputError(f"checkpoint JSON: model: {err}") from None
    except (TypeError, ValueError, KeyError, IndexError, RuntimeError) as err:
        raise InputError(f"checkpoint JSON: model: a network cannot be built from it ({type(err).__name__}: "
                         f"{str(err).splitlines()[0][:160] if str(err) else ''})") from None
    return config


def _of_type(value: Any, annotation: str) -> bool:
    """Whether a JSON value is of a ``ModelConfig`` field's annotated type (str, bool, int, float,
    tuple[int, ...], each optionally ``| None``), before anything is built from it."""
    kind, _, optional = annotation.partition(" | ")
    if value is None:
        return optional == "None"
    if kind == "tuple[int, ...]":
        return isinstance(value, list) and bool(value) and all(_of_type(v, "int") and v > 0 for v in value)
    if kind in ("int", "float") and isinstance(value, bool):
        return False
    return isinstance(value, {"str": str, "bool": bool, "int": int, "float": (int, float)}[kind])


def model_from_checkpoint(tensors: dict[str, torch.Tensor], document: dict[str, Any]) -> LiftingNetwork:
    model = LiftingNetwork(model_config(document))
    try:
        missing, unexpected = model.load_state_dict(unprefixed(tensors), strict=False)
    except RuntimeError as err:  # PyTorch's size dump: its first mismatch says enough
        mismatch = next((line.strip() for line in str(err).splitlines() if "size mismatch" in line), str(err)[:200])
        raise InputError(f"checkpoint does not fit its configuration: {mismatch}") from None
    if missing or unexpected:
        raise InputError(f"checkpoint does not fit its configuration (missing {missing[:3]}, "
                         f"unexpected {unexpected[:3]})")
    return model.eval()


# The model for detector keypoints of real footage, trained for them: it measures best on real detections, near
# and far (docs/RESULTS.md, issues 12 and 36); ground-truth-like H36M-17 input keeps the paper's model.
DETECTOR_MODEL = "ray3d-real"
H36M_MODEL = "ray3d"


def default_model(layout: str) -> str:
    """The shipped model that lifts keypoints of ``layout`` when the user names none: ``ray3d`` for H36M-17,
    ``ray3d-real`` for a detector's layout (COCO-17, Halpe-26, BlazePose-33, BODY-25, ...)."""
    return H36M_MODEL if layout == "h36m17" else DETECTOR_MODEL


def shipped_models() -> list[str]:
    folder = resources.files("ray3d").joinpath(SHIPPED_DIR)
    return sorted(p.name.removesuffix(".safetensors") for p in folder.iterdir() if p.name.endswith(".safetensors"))


def resolve(name_or_path: str | Path) -> Path:
    """A shipped model's name (``ray3d``, ``videopose3d``, ...) or a checkpoint path -> the .safetensors path."""
    path = Path(name_or_path)
    if path.suffix in (".safetensors", ".json") or path.exists():
        return path.with_suffix(".safetensors")
    shipped = resources.files("ray3d").joinpath(SHIPPED_DIR, f"{name_or_path}.safetensors")
    if str(name_or_path) == RFRH:
        raise InputError(f"{RFRH} is the no-learning baseline (the root only, at a fixed height), which ray3d evaluate "
                         f"compares against; it lifts no pose: choose a model ({', '.join(shipped_models())})",
                         arguments=("checkpoint",))
    if not shipped.is_file():
        raise InputError(f"no checkpoint {name_or_path!r}: not a file, and not a shipped model "
                         f"({', '.join(shipped_models()) or 'none shipped'}; {RFRH}, the no-learning baseline, "
                         "only in evaluation)", arguments=("checkpoint",))
    return Path(str(shipped))


def load_model(name_or_path: str | Path = "ray3d") -> tuple[LiftingNetwork, dict[str, Any]]:
    """A model in eval mode and its checkpoint document."""
    path = resolve(name_or_path)
    tensors, document = read_checkpoint(path)
    try:
        model_uncertainty(document)
        return model_from_checkpoint(tensors, document), document
    except InputError as err:
        raise InputError(f"{path.with_suffix('.json')}: {err.message}", arguments=err.arguments) from None


def export(source: str | Path, target: str | Path, overwrite: bool = False, averaged: bool = True,
           **provenance: Any) -> Path:
    """Copy a checkpoint's weights and configuration to ``target`` (.safetensors + .json), dropping training
    state (optimizer, RNG), adding ``provenance`` (e.g. the training command and time) to the JSON.
    ``averaged=False`` exports the last trained weights of a run that kept a moving average (its ``last``)."""
    tensors, document = read_checkpoint(resolve(source))
    weights = prefixed(unprefixed(tensors, MODEL_PREFIX if averaged else TRAINED_PREFIX), MODEL_PREFIX)
    if not weights:
        raise InputError(f"{source}: holds no {'averaged' if averaged else 'last trained'} weights")
    model_from_checkpoint(weights, document)  # refuse to export something that does not load
    target = refuse_existing(Path(target).with_suffix(".safetensors"), overwrite)
    keep = ("model", "trained_on", "epoch", "validation", "train_config")
    save_checkpoint(target, weights, {**{k: document[k] for k in keep if k in document}, **provenance})
    return target
