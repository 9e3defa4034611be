"""Camera lists as JSON: ``{"cameras": [camera, ...]}`` with each camera in ``Camera.to_dict`` form."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.io.atomic import atomic_path


def save_cameras(path: str | Path, cams: list[Camera], overwrite: bool = False, **info: Any) -> None:
    """Write cameras (and any extra top-level ``info``) atomically."""
    with atomic_path(path, overwrite) as temporary:
        temporary.write_text(json.dumps({**info, "cameras": [c.to_dict() for c in cams]}, indent=1))


def load_cameras(path: str | Path) -> list[Camera]:
    """Read a camera list, or a single camera object, from JSON."""
    path = Path(path)
    try:
        document = json.loads(path.read_text())
    except OSError as err:
        raise InputError(f"{path}: cannot read ({err.strerror})") from None
    except json.JSONDecodeError as err:
        raise InputError(f"{path}: not valid JSON ({err.msg} at line {err.lineno})") from None
    entries = document.get("cameras", [document]) if isinstance(document, dict) else document
    if not isinstance(entries, list) or not entries:
        raise InputError(f"{path}: expected a camera object or {{\"cameras\": [...]}}")
    cams = []
    for i, entry in enumerate(entries):
        try:
            cams.append(Camera.from_dict(entry, name=f"{path.stem}:{i}"))
        except InputError as err:
            raise InputError(f"{path}: camera {i}: {err}") from None
    return cams
