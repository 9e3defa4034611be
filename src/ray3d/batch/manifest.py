"""A batch manifest: the inputs of a batch job (videos or keypoint files), each with its camera and options.

CSV with a header row, or JSON (a list of objects, or ``{"inputs": [...]}``). Columns:

- ``input`` (required): a video or a keypoint file, relative to the manifest's folder unless absolute;
- ``name``: the input's output folder below the job's (default: the input's file name without suffix);
- the camera: ``camera`` (a camera file or ``h36m:SUBJECT:CAMERA_ID``), or ``camera_height``, ``pitch``,
  ``roll``, ``hfov`` or ``focal``, and ``image_size`` (``WIDTHxHEIGHT``; a video's own by default);
- the options of ``ray3d lift`` / ``ray3d video``, same names and defaults: ``checkpoint``, ``precision``,
  ``smooth_2d``, ``smooth_3d``, ``flip_test``, ``refine``, ``floor`` (a floor regions file), ``floor_z`` (where the
  floor lies in the camera's frame; default: observed from the people), ``frame`` (world or camera),
  ``format``, ``site`` (a site file: its report in ``NAME/site``, with ``every`` (15min) and ``start_time`` its
  counts per time bucket); for keypoints ``layout``, ``fps``, ``subject``,
  ``action`` and ``camera_index``; for videos ``detector``, ``fps``, ``start``, ``frames``, ``max_gap``,
  ``min_track``, ``rejoin`` and ``overlay`` (false: none drawn).

Everything is checked before any work starts: a manifest that is missing or empty, an unknown column, a value of
the wrong type, a missing input or camera file, two inputs with one name are refused with one line naming the
row and column. What is in the files is read by the job itself, so one bad input fails alone.
"""

from __future__ import annotations

import dataclasses
import datetime
import functools
import hashlib
import json
from pathlib import Path
from typing import Any

from ray3d.errors import InputError, reads_file
from ray3d.geometry import parse_image_size
from ray3d.io.text_files import read_csv_rows, read_json
from ray3d.io.world import FRAME_AXES, WRITTEN_FORMATS
from ray3d.jobs import CameraChoice, Job, input_kind
from ray3d.lifting.options import LiftOptions, VideoOptions
from ray3d.models.precision import PRECISIONS
from ray3d.temporal import SMOOTHING_METHODS, parse_duration

SMOOTHERS = (*SMOOTHING_METHODS, "none")


def _text(value: Any) -> str:
    return str(value)


def _number(value: Any) -> float:
    if isinstance(value, bool):
        raise ValueError("expected a number")
    return float(value)


def _count(value: Any) -> int:
    number = _number(value)
    if number != int(number) or number < 0:
        raise ValueError("expected a whole number >= 0")
    return int(number)


def _flag(value: Any) -> bool:
    if isinstance(value, bool):
        return value
    text = str(value).strip().lower()
    if text in ("true", "yes", "1"):
        return True
    if text in ("false", "no", "0"):
        return False
    raise ValueError("expected true or false")


def _wall_clock(value: Any) -> datetime.datetime:
    return datetime.datetime.fromisoformat(str(value))


def _choice(options: tuple[str, ...]):
    def check(value: Any) -> str:
        if str(value) not in options:
            raise ValueError(f"expected one of {', '.join(options)}")
        return str(value)
    return check


# column -> (parser, which inputs it applies to)
_BOTH = ("keypoints", "video")
COLUMNS: dict[str, tuple[Any, tuple[str, ...]]] = {
    "input": (_text, _BOTH), "name": (_text, _BOTH),
    "camera": (_text, _BOTH), "camera_height": (_number, _BOTH),
    "pitch": (_number, _BOTH), "roll": (_number, _BOTH),
    "hfov": (_number, _BOTH), "focal": (_number, _BOTH),
    "image_size": (lambda v: parse_image_size(v, "image_size"), _BOTH),
    "checkpoint": (_text, _BOTH), "precision": (_choice(PRECISIONS), _BOTH),
    "smooth_2d": (_choice(SMOOTHING_METHODS), _BOTH),
    "smooth_3d": (_choice(SMOOTHERS), _BOTH), "flip_test": (_flag, _BOTH),
    "refine": (_flag, _BOTH), "floor_z": (_number, _BOTH), "format": (_choice(WRITTEN_FORMATS), _BOTH),
    "floor": (_text, _BOTH), "frame": (_choice(tuple(FRAME_AXES)), _BOTH), "site": (_text, _BOTH),
    "every": (parse_duration, _BOTH), "start_time": (_wall_clock, _BOTH),
    "fps": (_number, _BOTH), "layout": (_text, ("keypoints",)), "subject": (_text, ("keypoints",)),
    "action": (_text, ("keypoints",)), "camera_index": (_count, ("keypoints",)),
    "detector": (_text, ("video",)), "start": (_count, ("video",)), "frames": (_count, ("video",)),
    "max_gap": (_number, ("video",)), "min_track": (_number, ("video",)), "rejoin": (_number, ("video",)),
    "overlay": (_flag, ("video",)),
}
CAMERA_COLUMNS = {"camera": "file", "camera_height": "camera_height", "pitch": "pitch", "roll": "roll",
                  "hfov": "hfov", "focal": "focal", "image_size": "image_size"}  # column -> CameraChoice field
LIFT_COLUMNS = ("smooth_2d", "smooth_3d", "flip_test", "refine", "frame", "floor_z")
PATH_COLUMNS = ("floor", "site")  # relative to the manifest's folder
_CHECK_IMAGE_SIZE = (1920, 1080)  # a video's camera is checked with this size before the video's own is read
VIDEO_COLUMNS = {"fps": "fps", "start": "start", "frames": "frames", "max_gap_s": "max_gap", "min_track_s": "min_track",
                 "rejoin_s": "rejoin"}


@dataclasses.dataclass(frozen=True)
class Entry:
    """One input of a batch job: ``options`` holds the manifest's values (parsed) for the columns it gave."""

    row: int
    input: Path
    name: str
    kind: str                      # "keypoints" or "video"
    options: dict[str, Any]

    def job(self) -> Job:
        """The entry as a ``ray3d.jobs.Job`` of one input (what ``ray3d lift`` / ``ray3d video`` would run)."""
        o = self.options
        return Job((self.input,), (CameraChoice(**{field: o[c] for c, field in CAMERA_COLUMNS.items() if c in o}),),
                   o.get("checkpoint"), o.get("precision", "fp32"),
                   LiftOptions(**{f: o[f] for f in LIFT_COLUMNS if f in o}), o.get("floor"), layout=o.get("layout"),
                   fps=o.get("fps") if self.kind == "keypoints" else None,
                   read_options={k: o[k] for k in ("subject", "action", "camera_index") if k in o},
                   detector=o.get("detector"), video=VideoOptions(**{field: o[column] for field, column in
                                                                    VIDEO_COLUMNS.items() if column in o}),
                   world_format=o.get("format", ".json"), overlay=o.get("overlay", True), site=o.get("site"),
                   every_s=o.get("every"), start_time=o.get("start_time"))

    def fingerprint(self) -> str:
        """What the entry's output depends on: its options, its input and camera files (size and time), and
        the model's weights. An output whose fingerprint matches is not made again."""
        from ray3d.checkpoints import DETECTOR_MODEL, H36M_MODEL, resolve

        def stamp(path: Path) -> list:
            stat = path.stat()
            return [str(path.resolve()), stat.st_size, stat.st_mtime_ns]

        camera = self.options.get("camera")
        files = [Path(self.options[c]) for c in ("floor", "site") if c in self.options]
        # Without a checkpoint the model follows the input's layout: both candidates count.
        models = [self.options["checkpoint"]] if "checkpoint" in self.options else [H36M_MODEL, DETECTOR_MODEL]
        document = {"kind": self.kind, "options": {k: v for k, v in self.options.items() if k != "name"},
                    "input": stamp(self.input),
                    "camera": stamp(Path(camera)) if camera and Path(camera).exists() else camera,
                    "files": [stamp(path) for path in files],
                    "model": [_file_hash(resolve(m)) for m in models]}
        return hashlib.sha256(json.dumps(document, sort_keys=True, default=str).encode()).hexdigest()


@functools.lru_cache(maxsize=None)
def _file_hash(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@reads_file("batch manifest")
def _rows(path: Path) -> list[dict[str, Any]]:
    if path.suffix.lower() == ".json":
        document = read_json(path)
        if isinstance(document, dict) and set(document) - {"inputs"}:
            raise InputError(f"{path}: unknown field {sorted(set(document) - {'inputs'})[0]!r} (a manifest holds "
                             "\"inputs\" only: assets/manifest.schema.json)")
        rows = document.get("inputs") if isinstance(document, dict) else document
        if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
            raise InputError(f"{path}: expected a list of inputs or {{\"inputs\": [...]}}, each an object")
        return rows
    rows = [row for row in read_csv_rows(path)
            if any((v or "").strip() for v in row.values() if isinstance(v, str))]
    if any(None in row for row in rows):
        raise InputError(f"{path}: a row has more values than the header has columns")
    return [{k.strip(): v.strip() for k, v in row.items() if v is not None and v.strip() != ""} for row in rows]


def read_manifest(path: str | Path) -> list[Entry]:
    """The checked entries of a manifest (see the module's description)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such manifest file", arguments=("manifest",))
    rows = _rows(path)
    if not rows:
        raise InputError(f"{path}: the manifest lists no inputs")
    entries, names = [], {}
    for number, row in enumerate(rows, start=1):
        try:
            entries.append(_entry(path, number, row, names))
        except OSError as err:  # a path the system will not look up (too long, ...): this row's, not a crash
            raise InputError(f"{path}: row {number}: {err.strerror or type(err).__name__}"
                             + (f": {str(err.filename)[:80]}" if err.filename else "")) from None
    return entries


def _entry(path: Path, number: int, row: dict, names: dict) -> Entry:
    """Row ``number`` of the manifest at ``path``, checked (``names``: the names given so far, to their rows)."""
    where = f"{path}: row {number}"
    unknown = sorted(set(row) - set(COLUMNS))
    if unknown:
        raise InputError(f"{where}: unknown column {unknown[0]!r} (known: {', '.join(COLUMNS)})")
    if "input" not in row:
        raise InputError(f"{where}: column 'input' is empty")
    source = Path(str(row["input"])).expanduser()
    source = source if source.is_absolute() else path.parent / source
    if not source.exists():
        raise InputError(f"{where}: column input: {source} does not exist")
    kind = input_kind(source)
    options = {}
    for column, value in row.items():
        parse, kinds = COLUMNS[column]
        if kind not in kinds:
            raise InputError(f"{where}: column {column} applies to {' and '.join(kinds)} inputs, not to {source}")
        try:
            options[column] = parse(value)
        except (ValueError, TypeError, InputError) as err:
            raise InputError(f"{where}: column {column}: {value!r}: {getattr(err, 'message', err)}") from None
    del options["input"]
    name = str(options.pop("name", source.stem))
    if not name or Path(name).name != name or name.startswith("."):
        raise InputError(f"{where}: column name: {name!r} is not a plain folder name")
    if name in names:
        raise InputError(f"{where}: name {name!r} is also row {names[name]}'s; give one of them a name column")
    names[name] = number
    checkpoint = Path(options.get("checkpoint", "")).expanduser()
    if checkpoint.suffix == ".safetensors" and not checkpoint.is_absolute():
        options["checkpoint"] = str(path.parent / checkpoint)
    for column in ("camera", *PATH_COLUMNS):
        if column in options and not options[column].startswith("h36m:"):
            given = Path(options[column]).expanduser()
            options[column] = str(given if given.is_absolute() else path.parent / given)
    for column in PATH_COLUMNS:
        if column in options and not Path(options[column]).is_file():
            raise InputError(f"{where}: column {column}: {options[column]} does not exist")
    entry = Entry(number, source, name, kind, options)
    try:
        job = entry.job()
    except InputError as err:
        raise InputError(f"{where}: {err.message}") from None
    try:  # a video's camera given by height and pitch waits for the video's image size
        job.cameras[0].camera(None if kind == "keypoints" else _CHECK_IMAGE_SIZE)
    except InputError as err:
        raise InputError(f"{where}: camera: {err.message}") from None
    return entry

