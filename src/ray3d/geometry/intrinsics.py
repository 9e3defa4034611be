"""A pinhole camera's intrinsics from what users know of it: an image size read from any of its forms, the focal
length from a horizontal field of view, and the intrinsics of a lens centred on the image."""

from __future__ import annotations

from typing import Any

import numpy as np

from ray3d.errors import InputError


def focal_from_hfov(width_px: float, hfov_deg: float) -> float:
    """Focal length in pixels of an image ``width_px`` wide spanning ``hfov_deg`` horizontally."""
    if not 0 < hfov_deg < 180:
        raise InputError(f"horizontal field of view must be in (0, 180) degrees, got {hfov_deg}",
                         arguments=("hfov_deg",))
    return width_px / 2 / np.tan(np.radians(hfov_deg) / 2)


def parse_image_size(value: Any, field: str = "image_size") -> tuple[int, int]:
    """(width, height) in pixels from a pair or a ``"WIDTHxHEIGHT"`` string; both must be positive integers."""
    try:
        parts = value.lower().split("x") if isinstance(value, str) else value
        width, height = (int(v) for v in parts)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{field}: expected (width, height) in pixels or WIDTHxHEIGHT, e.g. 1920x1080, got "
                         f"{value!r}") from None
    if width <= 0 or height <= 0:
        raise InputError(f"{field}: width and height must be positive, got {(width, height)}")
    return width, height


def pinhole_intrinsics(image_size: Any, focal_px: float | None = None,
                       hfov_deg: float | None = None) -> tuple[float, float, float, float]:
    """(fx, fy, cx, cy) of a lens with square pixels and its principal point at the image centre, from exactly
    one of its focal length in pixels and its horizontal field of view in degrees."""
    if (focal_px is None) == (hfov_deg is None):
        raise InputError("give exactly one of focal_px and hfov_deg", arguments=("focal_px", "hfov_deg"))
    width, height = parse_image_size(image_size)
    focal = focal_from_hfov(width, hfov_deg) if hfov_deg is not None else float(focal_px)
    if not focal > 0:
        raise InputError(f"focal_px: expected a positive focal length in pixels, got {focal_px}")
    return focal, focal, width / 2, height / 2
