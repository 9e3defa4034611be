"""A batch manifest: the inputs of a batch job (videos or keypoint files), each with its camera and options.

CSV with a header row, or JSON (a list of objects, or ``{"inputs": [...]}``). Columns:

- ``input`` (required): a video or a keypoint file, relative to the manifest's folder unless absolute;
- ``name``: the input's output folder below the job's (default: the input's file name without suffix);
- the camera: ``camera`` (a camera file or ``h36m:SUBJECT:CAMERA_ID``), or ``camera_height``, ``pitch``,
  ``roll``, ``hfov`` or ``focal``, and ``image_size`` (``WIDTHxHEIGHT``; a video's own by default);
- the options of ``ray3d lift`` / ``ray3d video``, same names and defaults: ``checkpoint``, ``precision``, ``smooth_2d``,
  ``smooth_3d``, ``flip_test``, ``refine``, ``format``; for keypoints ``layout`` and ``fps``; for videos
  ``detector``, ``fps``, ``start``, ``frames``, ``max_gap``, ``min_track``.

Everything is checked before any work starts: a manifest that is missing or empty, an unknown column, a value of
the wrong type, a missing input or camera file, two inputs with one name are refused with one line naming the
row and column. What is in the files is read by the job itself, so one bad input fails alone.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
from pathlib import Path
from typing import Any

from ray3d.errors import InputError, reads_file
from ray3d.geometry import Camera, parse_image_size
from ray3d.io.camera_files import camera_from_options, floor_of_camera_file
from ray3d.io.text_files import read_csv_rows, read_json
from ray3d.io.world import WRITTEN_FORMATS
from ray3d.models.precision import PRECISIONS
from ray3d.lifting.options import LiftOptions, VideoOptions
from ray3d.temporal import SMOOTHING_METHODS

VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg", ".wmv")
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
    "refine": (_flag, _BOTH), "format": (_choice(WRITTEN_FORMATS), _BOTH),
    "fps": (_number, _BOTH), "layout": (_text, ("keypoints",)),
    "detector": (_text, ("video",)), "start": (_count, ("video",)), "frames": (_count, ("video",)),
    "max_gap": (_number, ("video",)), "min_track": (_number, ("video",)),
}
CAMERA_COLUMNS = ("camera", "camera_height", "pitch", "roll", "hfov", "focal", "image_size")
LIFT_COLUMNS = ("smooth_2d", "smooth_3d", "flip_test", "refine")
_CHECK_IMAGE_SIZE = (1920, 1080)  # a video's camera is checked with this size before the video's own is read
VIDEO_COLUMNS = {"fps": "fps", "start": "start", "frames": "frames", "max_gap_s": "max_gap", "min_track_s": "min_track"}


@dataclasses.dataclass(frozen=True)
class Entry:
    """One input of a batch job: ``options`` holds the manifest's values (parsed) for the columns it gave."""

    row: int
    input: Path
    name: str
    kind: str                      # "keypoints" or "video"
    options: dict[str, Any]

    def camera(self, image_size: tuple[int, int] | None = None) -> Camera:
        """The entry's camera; ``image_size`` (a video's) is the default for a camera given by height and pitch."""
        return camera_from_options(**{c: self.options[c] for c in CAMERA_COLUMNS if c in self.options},
                                   default_image_size=image_size)

    def lift_options(self) -> LiftOptions:
        """The entry's lifting options; the floor is the one its camera file declares (z = 0 if none)."""
        return LiftOptions(**{f: self.options[f] for f in LIFT_COLUMNS if f in self.options},
                           floor=floor_of_camera_file(self.options.get("camera")))

    def video_options(self) -> VideoOptions:
        return VideoOptions(**{field: self.options[column] for field, column in VIDEO_COLUMNS.items()
                               if column in self.options})

    def fingerprint(self) -> str:
        """What the entry's output depends on: its options, its input and camera files (size and time), and
        the model's weights. An output whose fingerprint matches is not made again."""
        from ray3d.checkpoints import DETECTOR_MODEL, H36M_MODEL, resolve

        def stamp(path: Path) -> list:
            stat = path.stat()
            return [str(path.resolve()), stat.st_size, stat.st_mtime_ns]

        camera = self.options.get("camera")
        # Without a checkpoint the model follows the input's layout: both candidates count.
        models = [self.options["checkpoint"]] if "checkpoint" in self.options else [H36M_MODEL, DETECTOR_MODEL]
        document = {"kind": self.kind, "options": {k: v for k, v in self.options.items() if k != "name"},
                    "input": stamp(self.input),
                    "camera": stamp(Path(camera)) if camera and Path(camera).exists() else camera,
                    "model": [_file_hash(resolve(m)) for m in models]}
        return hashlib.sha256(json.dumps(document, sort_keys=True, default=str).encode()).hexdigest()


@functools.lru_cache(maxsize=None)
def _file_hash(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@reads_file("batch manifest")
def _rows(path: Path) -> list[dict[str, Any]]:
    if path.suffix.lower() == ".json":
        document = read_json(path)
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
        kind = "video" if source.suffix.lower() in VIDEO_SUFFIXES else "keypoints"
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
        if "camera" in options and not options["camera"].startswith("h36m:"):
            camera = Path(options["camera"]).expanduser()
            options["camera"] = str(camera if camera.is_absolute() else path.parent / camera)
        entry = Entry(number, source, name, kind, options)
        try:  # a video's camera given by height and pitch waits for the video's image size
            entry.camera(None if kind == "keypoints" else _CHECK_IMAGE_SIZE)
        except InputError as err:
            raise InputError(f"{where}: camera: {err.message}") from None
        try:
            entry.lift_options(), entry.video_options()
        except InputError as err:
            raise InputError(f"{where}: {err.message}") from None
        entries.append(entry)
    return entries
