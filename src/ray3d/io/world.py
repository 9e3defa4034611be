"""The lifted result and the world files that hold it: JSON, CSV and npz, each stating its units, axes, joint
names, frame rate, model and camera. ``write_world`` writes a ``World`` atomically (an existing file is replaced
only when asked); ``read_world`` gives the same ``World`` back."""

from __future__ import annotations

import csv
import dataclasses
import io
import json
from pathlib import Path

import numpy as np

from ray3d.errors import InputError, missing_fields, reads_file
from ray3d.geometry import Camera
from ray3d.geometry.uncertainty import Positioned
from ray3d.io.atomic import atomic_path
from ray3d.io.bvh_export import trc_text, write_bvh_files
from ray3d.io.safe_npz import read_npz_entries
from ray3d.io.text_files import read_json
from ray3d.skeleton import H36M17

FORMATS = (".json", ".csv", ".npz")
EXPORTS = (".trc", ".bvh")  # written for other tools, not read back
WRITTEN_FORMATS = FORMATS + EXPORTS  # every format a world can be written in: the one list
UNITS = "metres"
AXES = "world frame, right-handed: x and y horizontal, z up, floor at z = 0"
CAMERA_AXES = "camera frame (OpenCV): x right, y down, z forward along the optical axis, origin at the lens"
FRAME_AXES = {"world": AXES, "camera": CAMERA_AXES}
CSV_COLUMNS = ("frame", "track", "joint", "x", "y", "z", "interpolated", "position_sd_along_m", "position_sd_across_m")


def check_frame(frame: str) -> str:
    """``frame`` when it is one a world file can hold its joints in ("world" or "camera")."""
    if frame not in FRAME_AXES:
        raise InputError(f"frame must be one of {', '.join(FRAME_AXES)}, got {frame!r}", arguments=("frame",))
    return frame


def _per_track(document: dict, field: str, path: Path) -> dict[str, list]:
    """A world file's optional {track: list} field (``rejoined``, ``in_part``), checked for its shape."""
    value = document.get(field, {})
    if not isinstance(value, dict) or not all(isinstance(items, list) for items in value.values()):
        raise InputError(f"{path}: field {field}: not an object holding a list per track")
    return value


def _frame_described(axes: str) -> str:
    """The frame a file's axes text describes."""
    return "camera" if axes == CAMERA_AXES else "world"


@dataclasses.dataclass
class LiftResult(Positioned):
    """One person's world joints (T, 17, 3) in metres (z up, floor z = 0, H36M-17 order) at ``fps``, the frame
    index of each row (T,), which input joints were missing and filled in from neighbouring frames (T, 17), and
    the root's position uncertainty (T, 2): one standard deviation along the camera's ray through it and across
    that ray (per axis), metres (None in files from before 2026-12-04)."""

    joints: np.ndarray
    interpolated: np.ndarray
    fps: float
    frames: np.ndarray
    joint_names: tuple[str, ...] = H36M17.joint_names
    refinement: dict | None = None  # what ray3d.refine found (stature, scale, contact, uncertainty), if it ran
    position_sd: np.ndarray | None = None
    seen_by: np.ndarray | None = None  # (T, C) which of the world's cameras saw each frame (several cameras)

    @property
    def missing_fraction(self) -> float:
        return float(self.interpolated.mean())


@dataclasses.dataclass
class World:
    """Everything a world file holds: the people lifted from one camera, by track id, their joints in
    ``frame`` ("world", or "camera": see ``in_frame``), the camera and the model that lifted them, and the
    tracks that could not be lifted ({track id: why}; not written to files)."""

    tracks: dict[str, LiftResult]
    camera: Camera
    model: str
    units: str = UNITS
    frame: str = "world"
    path: Path | None = None  # the file it was read from
    unliftable: dict[str, str] = dataclasses.field(default_factory=dict)
    cameras: tuple[Camera, ...] = ()  # every camera, the first being ``camera``, when several saw the people
    rejoined: dict[str, list] = dataclasses.field(default_factory=dict)  # track -> the re-joins it holds (.json)
    in_part: dict[str, list[int]] = dataclasses.field(default_factory=dict)  # track -> frames the edge cut (.json)
    # What its people showed of the floor itself (``LiftedTracks.evidence`` and ``ankles``; not written to files):
    # what a camera's floor memory keeps (``io.floor_memory``).
    floor_evidence: tuple = ()

    def __post_init__(self) -> None:
        if not self.tracks:
            raise InputError("world: no tracks")
        self.cameras = tuple(self.cameras) or (self.camera,)
        check_frame(self.frame)
        self.tracks = {str(track): result for track, result in self.tracks.items()}
        self.unliftable = {str(track): why for track, why in self.unliftable.items()}

    @property
    def axes(self) -> str:
        """The frame in words, as the files state it."""
        return FRAME_AXES[self.frame]

    @property
    def fps(self) -> float:
        return next(iter(self.tracks.values())).fps

    @property
    def joint_names(self) -> tuple[str, ...]:
        return next(iter(self.tracks.values())).joint_names

    def track(self, name: str | None = None) -> LiftResult:
        """The track called ``name`` (default: the first)."""
        if name is None:
            return next(iter(self.tracks.values()))
        if str(name) not in self.tracks:
            raise InputError(f"{self.path or 'world'}: no track {name!r}; tracks: {', '.join(self.tracks)}",
                             arguments=("track",))
        return self.tracks[str(name)]

    def rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Every track's frames one after another: joints (N, 17, 3), frames (N,), tracks (N,), interpolated
        (N, 17), position uncertainty (N, 2) (NaN where a track has none)."""
        results = self.tracks.values()
        return (np.concatenate([r.joints for r in results]), np.concatenate([r.frames for r in results]),
                np.concatenate([[t] * len(r.joints) for t, r in self.tracks.items()]),
                np.concatenate([r.interpolated for r in results]),
                np.concatenate([np.full((len(r.joints), 2), np.nan) if r.position_sd is None else r.position_sd
                                for r in results]))

    def in_frame(self, frame: str) -> World:
        """The same people with their joints in the ``frame`` "world" (z up, floor z = 0) or "camera" (OpenCV:
        x right, y down, z forward, metres from the lens)."""
        if check_frame(frame) == self.frame:
            return self
        move = self.camera.world_to_camera if frame == "camera" else self.camera.camera_to_world
        tracks = {t: dataclasses.replace(r, joints=np.asarray(move(r.joints))) for t, r in self.tracks.items()}
        return dataclasses.replace(self, tracks=tracks, frame=frame)

    def refinements(self) -> dict[str, dict | None]:
        return {track: result.refinement for track, result in self.tracks.items()}

    def metadata(self) -> dict:
        return {"units": self.units, "axes": self.axes, "joint_names": list(self.joint_names), "fps": self.fps,
                "camera": self.camera.to_dict(), "model": self.model}


def _check_format(path: Path, formats: tuple[str, ...] = FORMATS) -> str:
    suffix = path.suffix.lower()
    if suffix not in formats:
        raise InputError(f"{path}: unknown world file format {suffix or '(none)'}; one of {', '.join(formats)}")
    return suffix


def check_world_output(path: str | Path, frame: str = "world") -> str:
    """The format of the world file ``path`` (its suffix), refused when unknown or when it cannot hold the
    joints in ``frame``: TRC and BVH are defined with the floor, in the world frame only."""
    path = Path(path)
    suffix = _check_format(path, FORMATS + EXPORTS)
    check_frame(frame)
    if suffix in EXPORTS and frame != "world":
        raise InputError(f"{path}: {suffix} files are written in the world frame (they need the floor); write the "
                         "camera frame as .json, .csv or .npz", arguments=("frame",))
    return suffix


def write_world(path: str | Path, world: World, overwrite: bool = False) -> Path:
    """Write ``world`` to ``path`` by its suffix: .json, .csv or .npz (read back by ``read_world``); .trc, the
    marker file of OpenSim and Pose2Sim (every joint a marker, ``TRACK_joint`` when there are several tracks;
    millimetres, y up as OpenSim expects); or .bvh, a skeleton with joint rotations for Blender, Maya and
    MotionBuilder (``ray3d.io.bvh_export``; one file per track, see ``export_paths``)."""
    path = Path(path)
    suffix = check_world_output(path, world.frame)
    if len(world.cameras) > 1 and suffix != ".json":
        raise InputError(f"{path}: a world of several cameras (which saw each frame) is written as .json",
                         arguments=("out",))
    if suffix == ".bvh":
        return write_bvh_files(path, world, overwrite)
    meta = world.metadata()
    joints, frames, tracks, interpolated, position_sd = world.rows()
    with atomic_path(path, overwrite) as temporary:
        if suffix == ".json":
            document = {**meta, "tracks": {t: {"frames": r.frames.tolist(), "joints": np.round(r.joints, 5).tolist(),
                                               "interpolated_input_joints": r.interpolated.astype(int).tolist(),
                                               "position_sd_m": (None if r.position_sd is None
                                                                 else np.round(r.position_sd, 4).tolist()),
                                               "refinement": r.refinement,
                                               **({} if r.seen_by is None else
                                                  {"seen_by": [np.flatnonzero(row).tolist() for row in r.seen_by]})}
                                           for t, r in world.tracks.items()},
                        **({"cameras": [c.to_dict() for c in world.cameras]} if len(world.cameras) > 1 else {}),
                        **({"rejoined": world.rejoined} if world.rejoined else {}),
                        **({"in_part": world.in_part} if world.in_part else {})}
            temporary.write_text(json.dumps(document))
        elif suffix == ".trc":
            temporary.write_text(trc_text(world, path.name))
        elif suffix == ".csv":
            with temporary.open("w", newline="") as handle:
                handle.write(_csv_header(world, world.refinements()))
                _write_csv_rows(handle, world)
        else:
            with temporary.open("wb") as handle:
                np.savez_compressed(handle, joints=joints.astype(np.float32), frames=frames, tracks=tracks,
                                    interpolated=interpolated, position_sd=position_sd.astype(np.float32),
                                    joint_names=np.array(world.joint_names),
                                    units=np.array(world.units), axes=np.array(world.axes), fps=np.array(world.fps),
                                    model=np.array(world.model), camera_json=np.array(json.dumps(meta["camera"])),
                                    refinement_json=np.array(json.dumps(world.refinements())))
    return path


def _csv_header(world: World, refinements: dict) -> str:
    meta = world.metadata()
    return (f"# units: {world.units}; axes: {world.axes}; fps: {world.fps:g}; model: {world.model}; "
            f"camera: {json.dumps(meta['camera'])}\n# refinement: {json.dumps(refinements)}\n"
            + ",".join(CSV_COLUMNS) + "\n")


def _write_csv_rows(handle, world: World) -> None:
    joints, frames, tracks, interpolated, position_sd = world.rows()
    writer = csv.writer(handle, lineterminator="\n")
    for i in range(len(joints)):
        for j, name in enumerate(world.joint_names):
            writer.writerow([frames[i], tracks[i], name, *(f"{v:.5f}" for v in joints[i, j]), int(interpolated[i, j]),
                             *("" if not np.isfinite(v) else f"{v:.4f}" for v in position_sd[i])])


def append_world_csv(path: str | Path, world: World) -> Path:
    """Add ``world``'s tracks to the CSV world file at ``path`` (made, with ``world``'s header, when it does not
    exist): each track's refinement on a comment line before its rows, then the rows, in one write. A reader
    meanwhile sees whole tracks (``read_world`` leaves out a track it catches half written): what ``ray3d live``
    writes as people leave."""
    path = Path(path)
    text = io.StringIO()
    if not path.exists():
        text.write(_csv_header(world, {}))
    for track, result in world.tracks.items():
        text.write(f"# refinement of track {json.dumps(track)}: {json.dumps(result.refinement)}\n")
        _write_csv_rows(text, World({track: result}, world.camera, world.model, world.units, world.frame))
    with path.open("a", newline="") as handle:
        handle.write(text.getvalue())
        handle.flush()
    return path


def _from_rows(joints, frames, tracks, interpolated, fps: float, joint_names,
               refinements: dict, position_sd=None) -> dict[str, LiftResult]:
    tracks = np.asarray(tracks).astype(str)

    def uncertainty(track: str) -> np.ndarray | None:
        values = None if position_sd is None else np.asarray(position_sd, dtype=np.float64)[tracks == track]
        return None if values is None or np.isnan(values).all() else values

    return {track: LiftResult(np.asarray(joints, dtype=np.float64)[tracks == track],
                              np.asarray(interpolated, dtype=bool)[tracks == track], float(fps),
                              np.asarray(frames, dtype=np.int64)[tracks == track], tuple(joint_names),
                              refinements.get(track), uncertainty(track))
            for track in dict.fromkeys(tracks.tolist())}


def _read_csv(path: Path) -> World:
    """Read row by row into compact columns (a live run's file may hold millions of rows)."""
    from array import array

    frames, tracks, interpolated = array("q"), [], array("b")
    xyz, sd = array("d"), array("d")
    names: dict[str, None] = {}
    refinements: dict = {}
    with path.open(newline="") as handle:
        header = handle.readline().removeprefix("#").strip()
        position = handle.tell()
        second = handle.readline()
        # Files from before 2026-12 have no refinement line, no interpolated column and no position uncertainty.
        if second.startswith("# refinement:"):
            refinements.update(json.loads(second.removeprefix("# refinement:")))
        else:
            handle.seek(position)
        columns = next(csv.reader([handle.readline()]))
        at = {name: columns.index(name) for name in columns}
        for line in handle:
            if not line.endswith("\n"):  # a line cut short by a file still being written: left out
                break
            if line.startswith("# refinement of track "):
                track, refinement = line.removeprefix("# refinement of track ").rstrip("\n").split(": ", 1)
                refinements[json.loads(track)] = json.loads(refinement)
                continue
            row = next(csv.reader([line]))
            names.setdefault(row[at["joint"]])
            xyz.extend((float(row[at["x"]]), float(row[at["y"]]), float(row[at["z"]])))
            interpolated.append(int(row[at["interpolated"]] or 0) if "interpolated" in at else 0)
            if len(interpolated) % len(names) == 1 or len(names) == 1:  # a frame's first joint
                frames.append(int(row[at["frame"]]))
                tracks.append(row[at["track"]])
                sd.extend(float(row[at[key]] or "nan") if key in at else np.nan for key in CSV_COLUMNS[-2:])
    fields = dict(part.split(": ", 1) for part in header.split("; camera: ", 1)[0].split("; "))
    camera = Camera.from_dict(json.loads(header.split("; camera: ", 1)[1]))
    if not names:
        raise InputError(f"{path}: no tracks yet")
    count = len(interpolated) // len(names)  # a frame caught half written is left out
    joints = np.frombuffer(xyz, dtype=np.float64)[:count * len(names) * 3].reshape(count, len(names), 3)
    flags = np.frombuffer(interpolated, dtype=np.int8)[:count * len(names)].reshape(count, len(names))
    position_sd = np.frombuffer(sd, dtype=np.float64).reshape(-1, 2)[:count]
    tracks_read = _from_rows(joints, np.frombuffer(frames, dtype=np.int64)[:count], tracks[:count], flags,
                             float(fields["fps"]), list(names), refinements, position_sd)
    return World(tracks_read, camera, fields.get("model", UNKNOWN_MODEL), fields["units"],
                 _frame_described(fields["axes"]), path)


def _optional_array(values) -> np.ndarray | None:
    return None if values is None else np.array(values, dtype=np.float64)


WORLD_FIELDS = ("units", "axes", "joint_names", "fps", "camera", "tracks")
UNKNOWN_MODEL = "unknown"  # a file that does not name the model that lifted its people (``model`` is optional)
TRACK_FIELDS = ("frames", "joints")  # what every version wrote; the fields added since are optional


def _require(document, fields: tuple[str, ...], where: str) -> None:
    missing = missing_fields(document, fields, where)
    if missing:
        raise InputError(f"{where}: not a world file written by ray3d: missing field(s) {', '.join(missing)} (every "
                         "version writes them)")


def _interpolated(entry: dict) -> np.ndarray:
    """A track's (frames, joints) flags of joints filled in; none where the file does not say."""
    if "interpolated_input_joints" in entry:
        return np.array(entry["interpolated_input_joints"], dtype=bool)
    return np.zeros(np.shape(entry["joints"])[:2], dtype=bool)


@reads_file("world file")
def read_world(path: str | Path) -> World:
    """Read back what :func:`write_world` wrote, in this version or an earlier one (files from before the
    refinement, the position uncertainty or several cameras read with those absent:
    ``tests/fixtures/old_worlds``)."""
    path = Path(path)
    suffix = _check_format(path)
    if not path.is_file():
        raise InputError(f"{path}: no such world file")
    try:
        if suffix == ".npz":
            data = read_npz_entries(path)
            tracks = _from_rows(data["joints"], data["frames"], data["tracks"], data["interpolated"],
                                float(data["fps"]), [str(n) for n in data["joint_names"]],
                                json.loads(str(data.get("refinement_json", "{}"))), data.get("position_sd"))
            return World(tracks, Camera.from_dict(json.loads(str(data["camera_json"]))),
                         str(data.get("model", UNKNOWN_MODEL)),
                         str(data["units"]), _frame_described(str(data["axes"])), path)
        if suffix == ".json":
            document = read_json(path)
            _require(document, WORLD_FIELDS, str(path))
            for t, entry in document["tracks"].items():
                _require(entry, TRACK_FIELDS, f"{path}: tracks[{t!r}]")
            cameras = tuple(Camera.from_dict(c) for c in document.get("cameras", [document["camera"]]))

            def seen_by(entry: dict) -> np.ndarray | None:
                if "seen_by" not in entry:
                    return None
                table = np.zeros((len(entry["seen_by"]), len(cameras)), bool)
                for row, which in enumerate(entry["seen_by"]):
                    table[row, which] = True
                return table

            tracks = {str(t): LiftResult(np.array(e["joints"], dtype=np.float64),
                                         _interpolated(e), float(document["fps"]),
                                         np.array(e["frames"], dtype=np.int64), tuple(document["joint_names"]),
                                         e.get("refinement"), _optional_array(e.get("position_sd_m")), seen_by(e))
                      for t, e in document["tracks"].items()}
            return World(tracks, Camera.from_dict(document["camera"]), str(document.get("model", UNKNOWN_MODEL)),
                         str(document["units"]), _frame_described(str(document["axes"])), path, cameras=cameras,
                         rejoined=_per_track(document, "rejoined", path), in_part=_per_track(document, "in_part", path))
        return _read_csv(path)
    except InputError:
        raise
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as err:
        raise InputError(f"{path}: not a world file written by ray3d ({type(err).__name__}: {err})") from None
