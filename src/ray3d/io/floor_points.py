"""Floor points for ``ray3d.calibrate.from_floor_points``: positions on the floor in metres and their pixels."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ray3d.errors import InputError, reads_file
from ray3d.io.text_files import read_csv_rows, read_json

MIN_FLOOR_POINTS = 4


@reads_file("floor-point file")
def read_floor_points(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(N, 2) floor positions in metres (z = 0) and (N, 2) pixels from a CSV (columns x, y, u, v) or a JSON list
    of {"x", "y", "u", "v"} objects."""
    path = Path(path)
    if path.suffix.lower() == ".json":
        rows = read_json(path)
        if not isinstance(rows, list):
            raise InputError(f"{path}: expected a list of {{\"x\", \"y\", \"u\", \"v\"}} objects")
    else:
        rows = read_csv_rows(path)
    try:
        values = np.array([[float(r[k]) for k in ("x", "y", "u", "v")] for r in rows])
    except (KeyError, TypeError):
        raise InputError(f"{path}: every floor point needs x, y (metres) and u, v (pixels)") from None
    except ValueError as err:
        raise InputError(f"{path}: non-numeric floor point value ({err})") from None
    if len(values) < MIN_FLOOR_POINTS:
        raise InputError(f"{path}: {len(values)} floor point(s); at least {MIN_FLOOR_POINTS} are needed")
    return values[:, :2], values[:, 2:]
