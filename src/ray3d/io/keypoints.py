"""2D keypoint files in: ours (npz / JSON / CSV), per-person results lists (COCO-style from detectron2 and
mmpose 0.x, AlphaPose's COCO-17 / Halpe-26 / Halpe-136, mmpose 1.x predictions), OpenPose per-frame JSON folders
(BODY_25), and VideoPose3D-style ``positions_2d`` npz. Every reader returns
``Keypoints``; every error names the file and what is wrong."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from ray3d.errors import InputError, reads_file
from ray3d.geometry.arrays import numeric_array
from ray3d.io.atomic import atomic_path
from ray3d.io.dataset_files import DATASET_FPS, load_positions_2d
from ray3d.io.detections import TrackDetections
from ray3d.io.frame_names import FrameNames
from ray3d.io.safe_npz import read_npz_entries
from ray3d.io.text_files import read_csv_rows, read_json
from ray3d.skeleton import LAYOUTS, convert_keypoints, identify_17_joint_layout, layout_named_by, layout_skeleton
from ray3d.temporal import check_frame_rate


@dataclasses.dataclass
class Keypoints:
    """Detections: pixels (N, J, 2), confidences (N, J) or None, frame index (N,) and track id (N,) per row."""

    pixels: np.ndarray
    confidences: np.ndarray | None
    frames: np.ndarray
    tracks: np.ndarray
    layout: str
    fps: float | None
    source: str
    path: Path | None = None
    untracked_dropped: int = 0  # detections left out: several people in a frame of a file without track ids
    frame_order: str | None = None  # how frames named by text (image names) were put in order, where they were
    # (``io.frame_names.FRAME_ORDERS``' words)

    def by_track(self) -> dict[object, TrackDetections]:
        """{track id: its detections} for ``Lifter.lift_tracks``."""
        out = {}
        for track in dict.fromkeys(self.tracks.tolist()):
            rows = self.tracks == track
            out[track] = TrackDetections(self.frames[rows], self.pixels[rows],
                                         None if self.confidences is None else self.confidences[rows])
        return out

    def h36m_pixels(self, track, frames: np.ndarray) -> np.ndarray:
        """(len(frames), 17, 2) the H36M-17 pixels of ``track`` (its id or the id's text) at ``frames``; NaN where
        it was not detected (to draw a lifted track over its input)."""
        out = np.full((len(frames), 17, 2), np.nan)
        rows = np.flatnonzero(self.tracks.astype(str) == str(track))
        if not len(rows):
            return out
        pixels, _ = convert_keypoints(self.pixels[rows], self.layout,
                                      None if self.confidences is None else self.confidences[rows])
        where = {int(f): i for i, f in enumerate(self.frames[rows])}
        for i, frame in enumerate(np.asarray(frames)):
            if int(frame) in where:
                out[i] = pixels[where[int(frame)]]
        return out

    def track(self, name=None) -> tuple[object, TrackDetections]:
        """(track id, its detections) of the track called ``name`` (its id or the id's text; default: the
        track with most detections)."""
        tracks = self.by_track()
        if name is None:
            chosen = max(tracks, key=lambda t: len(tracks[t].frames))
        else:
            found = [t for t in tracks if t == name or str(t) == str(name)]
            if not found:
                raise InputError(f"{self.path or self.source}: no track {name!r}; tracks: "
                                 f"{', '.join(map(str, tracks))}", arguments=("track",))
            chosen = found[0]
        return chosen, tracks[chosen]


def _layout_for(path: Path, pixels: np.ndarray, layout: str | None) -> str:
    joints = pixels.shape[1]
    if layout is not None:
        if layout_skeleton(layout).num_joints != joints:
            raise InputError(f"{path}: layout {layout} has {LAYOUTS[layout].num_joints} joints but the file has "
                             f"{joints}")
        return layout
    if joints == 17:  # COCO-17 and H36M-17 both have 17 joints: tell them apart by where the joints are
        found = identify_17_joint_layout(pixels)
        if found is None:
            raise InputError(f"{path}: 17 joints per detection, but their geometry fits neither COCO-17 nor H36M-17; "
                             "name the layout", arguments=("layout",))
        return found
    by_count = {33: "blazepose33", 25: "body25", 26: "halpe26"}
    if joints not in by_count:
        raise InputError(f"{path}: {joints} joints per detection matches no layout; name the layout "
                         f"({', '.join(f'{n}: {s.num_joints}' for n, s in LAYOUTS.items())})", arguments=("layout",))
    return by_count[joints]


def _numeric(path: Path, what: str, value) -> np.ndarray:
    return numeric_array(value, f"{path}: {what}")


def _finish(path: Path, pixels, confidences, frames, tracks, layout, fps, source) -> Keypoints:
    pixels = _numeric(path, "keypoints", pixels)
    if pixels.ndim != 3 or pixels.shape[-1] != 2 or len(pixels) == 0:
        raise InputError(f"{path}: keypoints must be (detections, joints, 2) with at least one detection, got "
                         f"{pixels.shape}")
    layout = _layout_for(path, pixels, layout)
    frames = np.arange(len(pixels)) if frames is None else _numeric(path, "frames", frames).astype(np.int64)
    tracks = np.zeros(len(pixels), dtype=np.int64) if tracks is None else np.asarray(tracks)
    if confidences is not None:
        confidences = _numeric(path, "confidences", confidences)
        if confidences.shape != pixels.shape[:2]:
            raise InputError(f"{path}: confidences must be {pixels.shape[:2]}, got {confidences.shape}")
    if len(frames) != len(pixels) or len(tracks) != len(pixels):
        raise InputError(f"{path}: frames and tracks need one entry per detection ({len(pixels)})")
    if fps is not None:
        check_frame_rate(fps, str(path))
    if len(frames) and (frames.min() < 0 or frames.max() - frames.min() > 10_000_000):
        raise InputError(f"{path}: frames: indices must be 0 or more and span at most 10,000,000 frames, got "
                         f"{frames.min()}-{frames.max()}")
    rows = np.stack([tracks.astype(str), frames.astype(str)], axis=-1)
    if len(np.unique(rows, axis=0)) < len(rows):
        raise InputError(f"{path}: the same frame appears more than once in one track (each person needs their "
                         "own track id)")
    return Keypoints(pixels, confidences, frames, tracks, layout, fps, source, path)


def _split_scores(path: Path, rows: np.ndarray, joints: int | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """Flat or nested (x, y[, score]) rows -> ((N, J, 2), (N, J) or None)."""
    if rows.ndim == 2:  # flat lists: x1 y1 s1 x2 y2 s2 ...
        if joints is None or rows.shape[1] != 3 * joints:
            raise InputError(f"{path}: keypoint lists of {rows.shape[1]} numbers; expected {joints} joints x "
                             "(x, y, score)")
        rows = rows.reshape(len(rows), joints, 3)
    if rows.ndim != 3 or rows.shape[-1] not in (2, 3):
        raise InputError(f"{path}: each keypoint needs (x, y) or (x, y, score), got shape {rows.shape}")
    return rows[..., :2], rows[..., 2] if rows.shape[-1] == 3 else None


def read_ours_json(path: Path, document: dict, layout, fps) -> Keypoints:
    detections = document.get("detections")
    if not isinstance(detections, list) or not detections:
        raise InputError(f"{path}: field 'detections' must be a non-empty list")
    try:
        rows = _numeric(path, "detections[].keypoints", [d["keypoints"] for d in detections])
        frames = [d.get("frame", i) for i, d in enumerate(detections)]
        tracks = [d.get("track", 0) for d in detections]
    except (KeyError, TypeError):
        raise InputError(f"{path}: every detection needs a 'keypoints' list") from None
    pixels, scores = _split_scores(path, rows)
    return _finish(path, pixels, scores, frames, tracks, layout or document.get("layout"),
                   document.get("fps") if fps is None else fps, "ray3d json")


# Whole-body layouts whose first joints are a body layout: COCO-WholeBody (133) starts with COCO-17, Halpe-136
# with Halpe-26. Their face, hand and foot points are not used.
_BODY_PREFIX = {17: "coco17", 26: "halpe26", 133: "coco17", 136: "halpe26"}


def _track_id(path: Path, value):
    """AlphaPose's ``idx`` (a number, or a list of them after PoseFlow), a ``track_id`` or OpenPose's
    ``person_id`` ([-1] when untracked); None when absent; refused when not a number or a name."""
    value = (value[0] if value else None) if isinstance(value, list) else value
    if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float, str))):
        raise InputError(f"{path}: a track id (track_id, idx, person_id) must be a number or a name, got {value!r:.40}")
    value = int(value) if isinstance(value, float) and value.is_integer() else value
    return None if value in (None, -1) else value


def read_results_list(path: Path, document: list, layout, fps) -> Keypoints:
    """Per-person results lists: COCO-style (detectron2, mmpose 0.x: flat ``keypoints`` and ``image_id``),
    AlphaPose's ``alphapose-results.json`` (``image_id`` an image name, ``idx`` the track with ``--pose_track``;
    COCO-17, Halpe-26 or Halpe-136), and mmpose 1.x predictions (``keypoints`` as [[x, y], ...] with
    ``keypoint_scores``): one image's list of instances, or a video's ``[{"frame_id", "instances": [...]}]``."""
    entries = []  # (frame, track or None, keypoints, scores or None, detection score)
    names = FrameNames(path)
    if all(isinstance(d, dict) and "instances" in d for d in document):
        for k, frame in enumerate(document):
            if not isinstance(frame["instances"], list):
                raise InputError(f"{path}: frame {k}: 'instances' must be a list")
            number = names.number(frame.get("frame_id", k), "frame_id")
            entries += [(number, _track_id(path, i.get("track_id")), i.get("keypoints"), i.get("keypoint_scores"),
                         i.get("bbox_score", i.get("score", 1.0))) for i in frame["instances"] if isinstance(i, dict)]
    elif all(isinstance(d, dict) and "keypoints" in d for d in document):
        image_level = not any("image_id" in d or "frame_index" in d for d in document)
        for d in document:  # one image's mmpose instances carry no frame
            field = "frame_index" if "frame_index" in d else "image_id"
            frame = 0 if image_level else names.number(d.get(field), field)
            entries.append((frame, _track_id(path, d.get("track_id", d.get("idx"))), d["keypoints"],
                            d.get("keypoint_scores"), d.get("score", d.get("bbox_score", 1.0))))
        if image_level:  # several people in one image are several tracks
            entries = [(f, k if t is None else t, kp, sc, score) for k, (f, t, kp, sc, score) in enumerate(entries)]
    else:
        raise InputError(f"{path}: a results list needs 'keypoints' in every entry (COCO, AlphaPose) or "
                         "'instances' in every entry (mmpose)")
    names.check()
    if not entries:
        raise InputError(f"{path}: the results list holds no person")
    rows = _numeric(path, "keypoints", [e[2] for e in entries])
    flat_joints = None
    if rows.ndim == 2:  # flat x1 y1 s1 x2 y2 s2 ...
        flat_joints = layout_skeleton(layout).num_joints if layout else rows.shape[1] // 3
        if rows.shape[1] != 3 * flat_joints or (layout is None and flat_joints not in _BODY_PREFIX):
            raise InputError(f"{path}: keypoint lists of {rows.shape[1]} numbers; expected 3 per joint for 17, 26, "
                             "133 or 136 joints (or name the layout)", arguments=("layout",))
    pixels, scores = _split_scores(path, rows, flat_joints)
    if scores is None and all(e[3] is not None for e in entries):
        scores = _numeric(path, "keypoint_scores", [e[3] for e in entries])
    if layout is None and pixels.shape[1] in _BODY_PREFIX:
        layout = _BODY_PREFIX[pixels.shape[1]]
        keep = layout_skeleton(layout).num_joints
        pixels, scores = pixels[:, :keep], None if scores is None else scores[:, :keep]
    frames = np.array([e[0] for e in entries], dtype=np.int64)
    tracks = [e[1] for e in entries]
    if all(t is None for t in tracks):
        # One person per frame without tracking: keep each frame's most confident detection.
        score = _numeric(path, "score", [e[4] for e in entries])
        best = {}
        for i, frame in enumerate(frames):
            if frame not in best or score[i] > score[best[frame]]:
                best[frame] = i
        keep = np.array(sorted(best.values()))
        dropped = len(frames) - len(keep)
        pixels, frames, tracks = pixels[keep], frames[keep], np.zeros(len(keep), dtype=np.int64)
        scores = None if scores is None else scores[keep]
    elif any(t is None for t in tracks):
        raise InputError(f"{path}: some entries have a track id and others none")
    else:
        tracks, dropped = np.array(tracks), 0
    read = _finish(path, pixels, scores, frames, tracks, layout, fps, "results list")
    return dataclasses.replace(read, untracked_dropped=dropped,
                               frame_order=names.order)


def read_openpose_folder(path: Path, layout, fps) -> Keypoints:
    files = sorted(path.glob("*_keypoints.json")) or sorted(path.glob("*.json"))
    if not files:
        raise InputError(f"{path}: no OpenPose *_keypoints.json files in this folder")
    pixels, scores, frames, tracks = [], [], [], []
    for frame, file in enumerate(files):
        document = read_json(file)
        people = document.get("people", []) if isinstance(document, dict) else None
        if not isinstance(people, list) or not all(isinstance(person, dict) for person in people):
            raise InputError(f"{file}: people: expected a list of people (OpenPose: {{\"people\": [{{...}}]}})")
        for order, person in enumerate(people):
            values = _numeric(file, "pose_keypoints_2d", person.get("pose_keypoints_2d", []))
            if values.size != 75:
                raise InputError(f"{file}: pose_keypoints_2d has {values.size} numbers; BODY_25 needs 75")
            values = values.reshape(25, 3)
            pixels.append(values[:, :2])
            scores.append(values[:, 2])
            frames.append(frame)
            person_id = _track_id(file, person.get("person_id"))
            tracks.append(order if person_id is None else person_id)
    if not pixels:
        raise InputError(f"{path}: no person detected in any of {len(files)} files")
    pixels, scores = np.array(pixels), np.array(scores)
    pixels[scores <= 0] = np.nan  # OpenPose writes (0, 0, 0) for joints it did not find
    return _finish(path, pixels, scores, frames, tracks, layout or "body25", fps, "openpose")


def read_csv(path: Path, layout, fps) -> Keypoints:
    rows = read_csv_rows(path)
    required = {"frame", "joint", "x", "y"}
    if not rows or not required <= set(rows[0]):
        raise InputError(f"{path}: CSV needs a header with {', '.join(sorted(required))} (optional track, score) "
                         "and at least one row")
    detections: dict[tuple, dict] = {}
    try:
        for row in rows:
            key = (int(row["frame"]), row.get("track") or "0")
            detections.setdefault(key, {})[row["joint"]] = (float(row["x"]), float(row["y"]),
                                                           float(row.get("score") or 1.0))
    except ValueError as err:
        raise InputError(f"{path}: frame, x, y or score: not numeric ({err})") from None
    joint_names = list(next(iter(detections.values())))
    if any(list(d) != joint_names for d in detections.values()):
        raise InputError(f"{path}: every (frame, track) must list the same joints in the same order")
    names_are_indices = all(j.isdigit() for j in joint_names)
    if layout is None and not names_are_indices:
        named = layout_named_by(joint_names)
        layout = named.name if named else None
    values = np.array([[d[j] for j in joint_names] for d in detections.values()])
    frames = [k[0] for k in detections]
    tracks = [k[1] for k in detections]
    return _finish(path, values[..., :2], values[..., 2], frames, tracks, layout, fps, "ray3d csv")


def read_npz(path: Path, layout, fps, subject=None, action=None, camera_index=None) -> Keypoints:
    entries = read_npz_entries(path)
    if "positions_2d" in entries:
        nested, _ = load_positions_2d(path, "h36m", entries)
        subject = subject or _only(path, "subject", list(nested))
        if subject not in nested:
            raise InputError(f"{path}: no subject {subject!r}; has {', '.join(map(str, nested))}")
        action = action or _only(path, "action", list(nested[subject]))
        if action not in nested[subject]:
            raise InputError(f"{path}: subject {subject} has no action {action!r}")
        per_camera = nested[subject][action]
        index = 0 if camera_index is None and len(per_camera) == 1 else camera_index
        if index is None or not 0 <= index < len(per_camera):
            raise InputError(f"{path}: choose a camera index 0..{len(per_camera) - 1}", arguments=("camera_index",))
        return _finish(path, per_camera[index], None, None, None, layout,
                       DATASET_FPS["h36m"] if fps is None else fps,
                       "videopose3d positions_2d")
    if "keypoints" not in entries:
        raise InputError(f"{path}: an npz of keypoints needs key 'keypoints' (or VideoPose3D's 'positions_2d')")
    stored_layout = entries.get("layout")
    stored_fps = entries.get("fps")
    return _finish(path, entries["keypoints"], entries.get("confidences"), entries.get("frames"),
                   entries.get("tracks"), layout or (str(stored_layout) if stored_layout is not None else None),
                   (float(stored_fps) if stored_fps is not None else None) if fps is None else fps, "ray3d npz")


def _only(path: Path, what: str, choices: list) -> str:
    if len(choices) != 1:
        raise InputError(f"{path}: several {what}s ({', '.join(map(str, choices[:8]))}); choose one",
                         arguments=(what,))
    return choices[0]


@reads_file("keypoint file")
def read_keypoints(path: str | Path, layout: str | None = None, fps: float | None = None, **npz_options) -> Keypoints:
    """Read any supported keypoint file (or OpenPose folder), detecting the format."""
    path = Path(path)
    if path.is_dir():
        return read_openpose_folder(path, layout, fps)
    if not path.is_file():
        raise InputError(f"{path}: no such file or folder")
    if path.stat().st_size == 0:
        raise InputError(f"{path}: the file is empty")
    suffix = path.suffix.lower()
    if suffix == ".npz":
        return read_npz(path, layout, fps, **npz_options)
    if suffix == ".csv":
        return read_csv(path, layout, fps)
    if suffix == ".json":
        document = read_json(path)
        if isinstance(document, list):
            return read_results_list(path, document, layout, fps)
        if isinstance(document, dict) and "people" in document:
            raise InputError(f"{path}: an OpenPose file: pass the folder holding all frames' files")
        if isinstance(document, dict):
            return read_ours_json(path, document, layout, fps)
    raise InputError(f"{path}: unknown keypoint format (expected .npz, .json, .csv or an OpenPose folder)")


def write_keypoints_json(path: str | Path, keypoints: Keypoints, overwrite: bool = False) -> Path:
    """Detections in our JSON format (read back by ``read_keypoints``): one row per detection with its frame
    index and track id; missing joints as confidence 0."""
    confidences = (np.ones(keypoints.pixels.shape[:2]) if keypoints.confidences is None
                   else np.where(np.isfinite(keypoints.pixels).all(-1), keypoints.confidences, 0.0))
    rows = np.concatenate([np.nan_to_num(keypoints.pixels), confidences[..., None]], axis=-1)
    document = {"layout": keypoints.layout, "fps": keypoints.fps, "detections": [
        {"frame": int(f), "track": int(t) if isinstance(t, (int, np.integer)) else str(t),
         "keypoints": np.round(r, 3).tolist()} for f, t, r in zip(keypoints.frames, keypoints.tracks, rows)]}
    with atomic_path(path, overwrite) as temporary:
        temporary.write_text(json.dumps(document))
    return Path(path)
