"""Site files (the zones and counting lines of ``ray3d.site``) and the tables a site's analysis writes: events
as JSON lines (``EventLines``, the one writer of them, live and offline) and CSV, per-track and per-place summaries
as CSV, each written atomically."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import TextIO

import numpy as np

from ray3d.errors import InputError, reads_file
from ray3d.geometry.arrays import numeric_array
from ray3d.geometry.floor import checked_polygon
from ray3d.io.atomic import atomic_path
from ray3d.io.text_files import read_json_or_yaml
from ray3d.site.checks import crossing_sides
from ray3d.site.places import CountingLine, FloorPlan, Site, Zone

SITE_TABLES = ("events.jsonl", "events.csv", "tracks.csv", "places.csv", "frames.csv", "occupancy.csv")


def _point(value, where: str) -> np.ndarray:
    point = numeric_array(value, where)
    if point.shape != (2,) or not np.isfinite(point).all():
        raise InputError(f"{where}: expected [x, y] in metres")
    return point


def _limit(entry: dict, key: str, kind: type, where: str):
    """A zone's optional rule: a positive number (a whole one for a count), or None when not given."""
    if key not in entry:
        return None
    value = entry[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value <= 0 \
            or (kind is int and value != int(value)):
        raise InputError(f"{where}: expected a positive {'whole number' if kind is int else 'number'}, got {value!r}")
    return kind(value)


def _floor_plan(entry, site_path: Path) -> FloorPlan:
    """A site file's ``floor_plan``: the picture (a path relative to the site file's folder), its metres per pixel
    and the world (x, y) of its bottom-left corner."""
    where = f"{site_path}: floor_plan"
    fields = {"image", "metres_per_pixel", "origin"}
    if not isinstance(entry, dict) or set(entry) != fields:
        raise InputError(f"{where}: expected the fields {', '.join(sorted(fields))}")
    scale = entry["metres_per_pixel"]
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not np.isfinite(scale) or scale <= 0:
        raise InputError(f"{where}.metres_per_pixel: expected a positive number, got {scale!r}")
    if not isinstance(entry["image"], str):
        raise InputError(f"{where}.image: expected the picture's path, got {entry['image']!r}")
    image_path = site_path.parent / entry["image"]
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(image_path) as picture:
            image = np.asarray(picture.convert("RGBA" if "A" in picture.getbands() else "RGB"))
    except FileNotFoundError:
        raise InputError(f"{where}.image: {image_path} does not exist") from None
    except (UnidentifiedImageError, OSError) as err:
        raise InputError(f"{where}.image: {image_path} is not a picture ({err})") from None
    return FloorPlan(image, float(scale), _point(entry["origin"], f"{where}.origin"))


@reads_file("site file")
def read_site(path: str | Path) -> Site:
    """A site file (JSON, or YAML as .yaml / .yml, the same fields; ``assets/site.schema.json``):
    ``{"zones": [{"name", "polygon": [[x, y], ...][, "max_occupancy", "max_dwell_s"]}], "lines": [{"name", "start":
    [x, y], "end": [x, y]}][, "floor_plan": {"image", "metres_per_pixel", "origin": [x, y]}]}`` in world metres;
    names must be unique within zones and within lines, and a zone's sides may not cross (its corners listed in
    order around it). Whether its places lie where the cameras and people are: ``site.checks.site_doubts``."""
    path = Path(path)
    document = read_json_or_yaml(path)
    if not isinstance(document, dict) or not (set(document) & {"zones", "lines"}):
        raise InputError(f"{path}: expected an object with zones and / or lines")
    unknown = set(document) - {"zones", "lines", "floor_plan"}
    if unknown:
        raise InputError(f"{path}: unknown field {sorted(unknown)[0]!r}")
    zones, lines = [], []
    for key, out in (("zones", zones), ("lines", lines)):
        entries = document.get(key, [])
        if not isinstance(entries, list):
            raise InputError(f"{path}: {key}: expected a list")
        for i, entry in enumerate(entries):
            where = f"{path}: {key}[{i}]"
            fields = {"name", "polygon"} if key == "zones" else {"name", "start", "end"}
            optional = {"max_occupancy", "max_dwell_s"} if key == "zones" else set()
            if not isinstance(entry, dict) or not fields <= set(entry) <= fields | optional:
                raise InputError(f"{where}: expected the fields {', '.join(sorted(fields))}"
                                 + (f" (and optionally {', '.join(sorted(optional))})" if optional else ""))
            name = str(entry["name"])
            if any(item.name == name for item in out):
                raise InputError(f"{where}.name: {name!r} is used twice")
            if key == "zones":
                polygon = numeric_array(entry["polygon"], f"{where}.polygon")
                crossing = (crossing_sides(polygon) if polygon.ndim == 2 and polygon.shape[1:] == (2,)
                            and np.isfinite(polygon).all() else None)  # before its area: a bow tie's is 0
                if crossing is not None:  # its corners out of order: what is inside it is not what was meant
                    first, second, point = crossing
                    raise InputError(f"{where}: zone {name!r} crosses itself: its sides from polygon[{first}] and "
                                     f"from polygon[{second}] meet at ({point[0]:.2f}, {point[1]:.2f}); list its "
                                     "corners in order around its edge")
                polygon = checked_polygon(polygon, f"{where}.polygon")
                out.append(Zone(name, polygon, _limit(entry, "max_occupancy", int, f"{where}.max_occupancy"),
                                _limit(entry, "max_dwell_s", float, f"{where}.max_dwell_s")))
            else:
                start, end = _point(entry["start"], f"{where}.start"), _point(entry["end"], f"{where}.end")
                if np.linalg.norm(end - start) < 0.01:
                    raise InputError(f"{where}: start and end are the same point")
                out.append(CountingLine(name, start, end))
    floor_plan = _floor_plan(document["floor_plan"], path) if "floor_plan" in document else None
    return Site(tuple(zones), tuple(lines), floor_plan)



class EventLines:
    """Events as JSON lines in ``path`` (appended, flushed with each write, so nothing written is lost when the
    process ends) and, if given, on ``echo`` (say stdout)."""

    def __init__(self, path: str | Path, echo: TextIO | None = None):
        self.path, self.echo = Path(path), echo
        self._file = self.path.open("a")

    def write(self, events: list[dict]) -> None:
        if not events:
            return
        text = "".join(json.dumps(event) + "\n" for event in events)
        self._file.write(text)
        self._file.flush()
        if self.echo is not None:
            try:
                self.echo.write(text)
                self.echo.flush()
            except BrokenPipeError:  # a reader of stdout that stopped reading: the file still has every event
                self.echo = None

    def close(self) -> None:
        self._file.close()


def write_site_tables(out_dir: str | Path, events: list[dict], tracks: list[dict], places: list[dict],
                      frames: list[dict], occupancy: list[dict], overwrite: bool = False) -> list[Path]:
    """``SITE_TABLES`` in ``out_dir`` (created): every event as a JSON line and a CSV row (lists as JSON text),
    the per-track, per-place, per-person-frame and occupancy tables as CSV."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / name for name in SITE_TABLES]
    with atomic_path(paths[0], overwrite) as temporary:
        lines = EventLines(temporary)
        lines.write(events)
        lines.close()
    for path, rows in zip(paths[1:], (events, tracks, places, frames, occupancy)):
        write_csv(path, rows, overwrite)
    return paths


def write_csv(path: Path, rows: list[dict], overwrite: bool = False) -> Path:
    """``rows`` as a CSV table (the columns of every row, in the order first met; lists as JSON text)."""
    columns = list(dict.fromkeys(key for row in rows for key in row))
    with atomic_path(path, overwrite) as temporary, temporary.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, columns)
        writer.writeheader()
        writer.writerows({k: json.dumps(v) if isinstance(v, list) else v for k, v in row.items()} for row in rows)
    return path
