"""Backend helpers so every geometry function accepts numpy arrays and torch tensors alike.

Rules: the input's library, dtype and device decide the output's; integer or list input becomes float64
(numpy) or the default float dtype (torch); torch inputs keep autograd.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from ray3d.errors import InputError

Array = Any  # np.ndarray | torch.Tensor


def namespace(x: Array):
    """The module (numpy or torch) whose functions operate on ``x``."""
    return torch if isinstance(x, torch.Tensor) else np


def as_float(x: Array) -> Array:
    """``x`` as a floating array of its own library; lists and integer arrays become float."""
    if isinstance(x, torch.Tensor):
        return x if x.is_floating_point() else x.to(torch.get_default_dtype())
    x = np.asarray(x)
    return x if np.issubdtype(x.dtype, np.floating) else x.astype(np.float64)


def numeric_array(value: Any, what: str) -> np.ndarray:
    """``value`` (numbers, nested lists of them) as a float64 numpy array; anything else is refused as
    ``what`` being not numeric."""
    try:
        return np.asarray(value, dtype=np.float64)
    except OverflowError:
        raise InputError(f"{what}: a number too large to be a float") from None
    except (TypeError, ValueError) as err:
        if "inhomogeneous" in str(err):
            raise InputError(f"{what}: rows of different lengths") from None
        raise InputError(f"{what}: not numeric") from None


def to_numpy(x: Array) -> np.ndarray:
    """A numpy copy of ``x`` (torch tensors are detached and moved to the CPU)."""
    return x.detach().cpu().numpy() if isinstance(x, torch.Tensor) else np.asarray(x)


def like(value: Array, ref: Array) -> Array:
    """``value`` (numpy or torch) converted to the library, dtype and device of ``ref``."""
    if isinstance(ref, torch.Tensor):
        if isinstance(value, np.ndarray) and not value.flags.writeable:
            value = value.copy()  # torch cannot wrap read-only memory (our frozen camera arrays)
        return torch.as_tensor(value, dtype=ref.dtype, device=ref.device)
    return np.asarray(value, dtype=ref.dtype)


def stack_last(parts: list[Array]) -> Array:
    """Broadcast arrays of one library against each other and stack them along a new last axis."""
    if isinstance(parts[0], torch.Tensor):
        return torch.stack(torch.broadcast_tensors(*parts), -1)
    return np.stack(np.broadcast_arrays(*parts), -1)


def check_points(x: Array, dim: int, name: str) -> Array:
    """Validate a ``(..., dim)`` array of finite coordinates and return it as floats.

    Raises:
        InputError: naming ``name`` when the last axis is not ``dim`` or a value is NaN or infinite.
    """
    try:
        x = as_float(x)
    except (TypeError, ValueError) as err:
        raise InputError(f"{name}: not a numeric array ({err})") from None
    if x.ndim == 0 or x.shape[-1] != dim:
        raise InputError(f"{name}: expected shape (..., {dim}), got {tuple(x.shape)}")
    finite = torch.isfinite(x).all().item() if isinstance(x, torch.Tensor) else np.isfinite(x).all()
    if not finite:
        raise InputError(f"{name}: contains NaN or infinite values")
    return x
