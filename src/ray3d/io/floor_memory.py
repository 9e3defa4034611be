"""What a camera's people have shown of its floor, remembered run after run (issue 66), so that a camera watched
for a week knows its floor better than one clip does: each run's evidence of the floor itself
(``refine.ankle_plane.floor_evidence``: people's sizes against their drop from the camera, and ankles two cameras
saw at once), kept in a file beside an offline job's camera file (``floor_memory_path``) and given back to the
next lift as ``LiftOptions.seen_before`` (``jobs.Job.remembered_floor``). Lifting the same input again replaces
its run rather than adding it; a camera moved or recalibrated (its centre no longer where the runs saw it) starts
afresh. What is shared by every run, a site's people's mean size and the detector's, is not averaged away however
many runs there are: the decision (``decide_ankle_plane``) keeps it."""

from __future__ import annotations

import dataclasses
import datetime
import json
from pathlib import Path

import numpy as np

from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.io.atomic import write_text
from ray3d.refine.ankle_plane import SeenTwice, SizeEvidence

FORMAT = "ray3d floor memory"
VERSION = 1
MAX_RUNS = 1000        # the oldest runs are forgotten beyond this
SAME_CAMERA_M = 0.01   # a camera centre moved further than this is another calibration


@dataclasses.dataclass(frozen=True)
class RememberedRun:
    """One run's evidence of a camera's floor: ``key`` names what it lifted (``input_key``), ``when`` it ran, the
    camera ``centre`` it saw it from, each person's ``SizeEvidence`` and each person seen by two cameras at once
    (``SeenTwice``), all of the floor itself."""

    key: str
    when: str
    centre: tuple[float, float, float]
    people: tuple[SizeEvidence, ...] = ()
    ankles: tuple[SeenTwice, ...] = ()


def floor_memory_path(camera: str | Path) -> Path | None:
    """Where a camera file's floor memory lies: beside it, ``<name>.floor.json`` (a camera of a file of several,
    ``FILE.toml:NAME``: ``<file name>.<NAME>.floor.json``); None for a camera that is not a file."""
    camera = str(camera)
    if Path(camera).is_file():
        return Path(camera).with_name(f"{Path(camera).stem}.floor.json")
    file, _, name = camera.rpartition(":")
    if file and Path(file).is_file():
        return Path(file).with_name(f"{Path(file).stem}.{name}.floor.json")
    return None


def input_key(*inputs: str | Path) -> str:
    """What names a run's inputs: their paths, sizes and modification times (the same files lifted again are the
    same run)."""
    def one(path: Path) -> str:
        stat = path.stat() if path.exists() else None
        return f"{path.resolve()}:{stat.st_size}:{stat.st_mtime_ns}" if stat else str(path)

    return "|".join(one(Path(path)) for path in inputs)


def read_floor_memory(path: str | Path, camera: Camera) -> list[RememberedRun]:
    """The runs a floor memory file holds that saw ``camera`` where it is now (none when the file does not exist);
    an ``InputError`` naming the file and field when it is not a floor memory."""
    path = Path(path)
    if not path.exists():
        return []
    try:
        document = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise InputError(f"{path}: not a floor memory file ({err})") from None
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise InputError(f"{path}: format: expected {FORMAT!r}; not a floor memory file")
    if document.get("version") != VERSION:
        raise InputError(f"{path}: version: this ray3d reads version {VERSION}, got {document.get('version')!r}")
    runs = document.get("runs")
    if not isinstance(runs, list):
        raise InputError(f"{path}: runs: expected a list")
    remembered = [_run(entry, path, k) for k, entry in enumerate(runs)]
    return [run for run in remembered if np.linalg.norm(np.subtract(run.centre, camera.center)) <= SAME_CAMERA_M]


def _run(entry, path: Path, k: int) -> RememberedRun:
    where = f"{path}: runs[{k}]"
    try:
        people = tuple(SizeEvidence(*map(float, person)) for person in entry["people"])
        ankles = tuple(SeenTwice(*map(float, ankle)) for ankle in entry["ankles"])
        centre = tuple(float(v) for v in entry["centre"])
        key, when = str(entry["key"]), str(entry["when"])
    except (KeyError, TypeError, ValueError) as err:
        raise InputError(f"{where}: expected key, when, centre [x, y, z], people [[centre_z, log_size_over_drop, "
                         f"seconds], ...] and ankles [[height_m, sd_m, seconds], ...] ({err})") from None
    numbers = [*centre, *(v for e in (*people, *ankles) for v in dataclasses.astuple(e))]
    if len(centre) != 3 or not np.isfinite(numbers).all():
        raise InputError(f"{where}: centre and evidence must be finite numbers, centre three of them")
    return RememberedRun(key, when, centre, people, ankles)


def remember_floor(path: str | Path, camera: Camera, key: str, people: tuple, ankles: tuple) -> RememberedRun:
    """Adds a run's evidence (``people``: ``SizeEvidence``, ``ankles``: ``SeenTwice``, of the floor itself) to the
    floor memory at ``path`` seen from ``camera``, replacing an earlier run of the same ``key`` and forgetting the
    oldest beyond ``MAX_RUNS`` and the runs of another calibration; written atomically. Returns the run."""
    def rounded(values) -> list[float]:
        return [round(float(v), 6) for v in values]

    run = RememberedRun(key, datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                        tuple(rounded(camera.center)), tuple(SizeEvidence(*rounded(dataclasses.astuple(e)))
                                                             for e in people),
                        tuple(SeenTwice(*rounded(dataclasses.astuple(e)[:3])) for e in ankles))
    runs = [earlier for earlier in read_floor_memory(path, camera) if earlier.key != key][-(MAX_RUNS - 1):]
    document = {"format": FORMAT, "version": VERSION,
                "about": "What this camera's people showed of its floor, run by run (ray3d, docs/floor.md); "
                         "delete it to forget.",
                "runs": [{"key": r.key, "when": r.when, "centre": list(r.centre),
                          "people": [list(dataclasses.astuple(e)) for e in r.people],
                          "ankles": [list(dataclasses.astuple(e)[:3]) for e in r.ankles]}
                         for r in (*runs, run)]}
    write_text(path, json.dumps(document, indent=1) + "\n", overwrite=True)
    return run

