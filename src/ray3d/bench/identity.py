"""Who is who, against identities annotated by hand (``ray3d bench identity``): ``ray3d video``'s floor tracker
(with and without its re-joins) and the maintained trackers of the ``trackers`` package (ByteTrack, OC-SORT, SORT)
on the same detections, scored with the standard multi-object-tracking metrics (IDF1, ID switches, MOTA; that
package's port of TrackEval). A tracker's box counts for the annotated box it overlaps at IoU >= 0.5.

The annotation shipped (``ANNOTATION``: every stay in view of the 795 frames of ``vtest.avi``, 21 people) and how it
was made: ``bench/data/vtest_identities.md``. Needs the video extra and the ``trackers`` package (its pins in
constraints.txt: ``pip install -c constraints.txt --no-deps trackers supervision pydeprecate defusedxml rich
markdown-it-py mdurl pygments requests``)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from ray3d.errors import InputError
from ray3d.jobs import Job, video_input
from ray3d.lifting.options import VideoOptions
from ray3d.skeleton import BLAZEPOSE33
from ray3d.video import read_frames
from ray3d.video.boxes import box_overlap
from ray3d.video.detectors import Detection
from ray3d.video.frames import spread_frames
from ray3d.video.pipeline import follow_people
from ray3d.video.tracking import CONFIRM_FRAMES, FloorTracker

ANNOTATION = Path(__file__).parent / "data" / "vtest_identities.csv"
MATCH_IOU = 0.5  # a tracker's box is the annotated box it overlaps this much
FIRST_DISTRACTOR = 10_000  # the MOT ids of unannotated detections start here, past any annotated person's number


def detect(info, finder, out: Path) -> Path:
    """Every detection of the video's frames (``info``: its ``VideoInfo``) by ``finder`` (a job's detector),
    written to the npz ``out``: frame index, pixels, confidences, person score (one row each), the layout, frame rate
    and frame count."""
    finder.prepare(spread_frames(info, 0, info.frames))
    frames, pixels, confidences, scores = [], [], [], []
    for index, frame in read_frames(info.path):
        for detection in finder(frame):
            frames.append(index)
            pixels.append(detection.pixels)
            confidences.append(detection.confidences)
            scores.append(detection.score)
    np.savez_compressed(out, frames=np.array(frames), pixels=np.array(pixels), confidences=np.array(confidences),
                        scores=np.array(scores), fps=info.fps, frame_count=info.frames, layout=finder.layout)
    return out


def load_detections(path: Path) -> tuple[dict[int, list[Detection]], float, int, str]:
    """{frame: its detections}, the frame rate, the frame count and the keypoint layout of a ``detect`` file (files
    written before the layout was kept hold BlazePose-33 keypoints)."""
    try:
        data = np.load(path)
        by_frame: dict[int, list[Detection]] = {i: [] for i in range(int(data["frame_count"]))}
        for frame, pixels, confidences, score in zip(data["frames"], data["pixels"], data["confidences"],
                                                     data["scores"]):
            by_frame[int(frame)].append(Detection(pixels, confidences, float(score)))
        layout = str(data["layout"]) if "layout" in data else BLAZEPOSE33.name
        return by_frame, float(data["fps"]), int(data["frame_count"]), layout
    except (OSError, ValueError, KeyError) as error:
        raise InputError(f"--detections {path}: not the detections of `ray3d bench identity` ({error})") from None


def floor_tracks(by_frame: dict[int, list[Detection]], frame_count: int, fps: float, layout: str, camera,
                 video: Path, rejoin_s: float = 0.0) -> list:
    """The floor tracker's tracks of these detections: ``ray3d video``'s before its re-joins, or with ``rejoin_s``
    ``ray3d live``'s (re-joined as it goes)."""
    tracker = FloorTracker(camera, fps, layout, VideoOptions().max_gap_s, CONFIRM_FRAMES, rejoin_s=rejoin_s)
    for index, frame in read_frames(video, 0, frame_count):
        tracker.update(index, by_frame[index], frame)
    return tracker.tracks()


def _mot_row(frame: int, identity: int, box, kind: int = 1) -> str:
    """One MOT-challenge line: frame (from 1), id, left, top, width, height, conf, class."""
    x0, y0, x1, y1 = box
    return f"{frame + 1},{identity},{x0:.1f},{y0:.1f},{x1 - x0:.1f},{y1 - y0:.1f},1,{kind},1\n"


def read_annotation(path: Path) -> dict[int, list[tuple[str, np.ndarray]]]:
    """{frame: [(person, box (4,))]} of an annotation CSV (frame, person, x0, y0, x1, y1)."""
    annotated: dict[int, list[tuple[str, np.ndarray]]] = {}
    line = 1
    try:
        with open(path, newline="") as stream:
            for line, row in enumerate(csv.DictReader(stream), start=2):
                box = np.array([float(row[k]) for k in ("x0", "y0", "x1", "y1")])
                annotated.setdefault(int(row["frame"]), []).append((row["person"], box))
    except (OSError, KeyError, TypeError, ValueError) as error:
        raise InputError(f"{path} line {line}: not an annotation row (frame, person, x0, y0, x1, y1): {error}") \
            from None
    return annotated


def write_truth(by_frame: dict[int, list[Detection]], annotated: dict, path: Path) -> int:
    """The annotation as MOT ground truth, written to ``path``: each annotated box a pedestrian with its person's
    number; every detection that overlaps no annotated box at ``MATCH_IOU`` a distractor (class 8: a tracker's box
    on it is neither right nor wrong). By overlap, not equality: the annotation's boxes are one detector's, and
    another detector's box on an annotated person must count for them. Returns the number of people."""
    numbers: dict[str, int] = {}
    lines, distractor = [], FIRST_DISTRACTOR
    for frame, detections in by_frame.items():
        boxes = annotated.get(frame, [])
        lines += [_mot_row(frame, numbers.setdefault(person, len(numbers) + 1), box) for person, box in boxes]
        for detection in detections:
            if not boxes or box_overlap(detection.box[None], np.stack([box for _, box in boxes])).max() < MATCH_IOU:
                distractor += 1
                lines.append(_mot_row(frame, distractor, detection.box, kind=8))
    path.write_text("".join(lines))
    return len(numbers)


def run_trackers(by_frame, frame_count: int, fps: float, layout: str, camera, video: Path,
                 min_track_s: float) -> dict[str, dict[int, list]]:
    """{tracker: {frame: [(track id, box)]}}: the floor tracker with and without its re-joins (``ray3d video``'s
    after the whole tracks, ``ray3d live``'s as it goes), and the ``trackers`` package's ByteTrack, OC-SORT and
    SORT at their defaults (given the video's frame rate), all on the same detections (boxes of the confident
    joints, the person score); every tracker's tracks followed for less than ``min_track_s`` left out, as ``ray3d
    video`` leaves out its own."""
    sv, maintained, _ = trackers_package()
    results: dict[str, dict[int, list]] = {}
    whole = floor_tracks(by_frame, frame_count, fps, layout, camera, video)
    as_it_goes = floor_tracks(by_frame, frame_count, fps, layout, camera, video, VideoOptions().rejoin_s)
    for name, tracks, rejoin_s in (("floor tracker + re-join", whole, VideoOptions().rejoin_s),
                                   ("floor tracker + re-join as it goes", as_it_goes, 0.0),
                                   ("floor tracker", whole, 0.0)):
        found = results[name] = {}
        options = VideoOptions(rejoin_s=rejoin_s, min_track_s=min_track_s)
        for number, track in enumerate(follow_people(tracks, fps, frame_count, options).kept):
            for frame, detection in zip(track.frames, track.detections):
                found.setdefault(frame, []).append((number + 1, detection.box))
    for name, make in maintained.items():
        tracker, found = make(frame_rate=fps), {}
        for frame in range(frame_count):
            detections = by_frame[frame]
            boxes = np.array([d.box for d in detections], dtype=np.float32).reshape(-1, 4)
            given = sv.Detections(xyxy=boxes, confidence=np.array([d.score for d in detections], dtype=np.float32),
                                  class_id=np.zeros(len(detections), dtype=int))
            tracked = tracker.update(given)
            found[frame] = [(int(i) + 1, box) for i, box in zip(tracked.tracker_id, tracked.xyxy) if i >= 0]
        results[name] = without_short_tracks(found, fps, min_track_s)
    return results


def trackers_package():
    """The ``supervision`` module, {name: tracker class} of the ``trackers`` package and its scoring function."""
    try:
        import supervision as sv
        from trackers import ByteTrackTracker, OCSORTTracker, SORTTracker
        from trackers.eval import evaluate_mot_sequence
    except ImportError:
        raise InputError("bench identity needs the trackers package: pip install -c constraints.txt --no-deps "
                         "trackers supervision pydeprecate defusedxml rich markdown-it-py mdurl pygments "
                         "requests") from None
    return sv, {"ByteTrack": ByteTrackTracker, "OC-SORT": OCSORTTracker, "SORT": SORTTracker}, evaluate_mot_sequence


def without_short_tracks(found: dict[int, list], fps: float, min_track_s: float) -> dict[int, list]:
    """A tracker's {frame: [(track id, box)]} less the tracks followed (first to last frame) for less than
    ``min_track_s``: the rule of ``ray3d.video.pipeline.follow_people``, on a maintained tracker's tracks."""
    frames: dict[int, list[int]] = {}
    for frame, rows in found.items():
        for identity, _ in rows:
            frames.setdefault(identity, []).append(frame)
    short = {i for i, seen in frames.items() if (max(seen) - min(seen) + 1) / fps < min_track_s}
    return {frame: [(i, box) for i, box in rows if i not in short] for frame, rows in found.items()}


def compare(detections: Path, video: Path, camera, out: Path, annotation: Path = ANNOTATION,
            min_track_s: float = VideoOptions().min_track_s) -> dict:
    """Each tracker on the ``detections`` of ``video`` seen by ``camera`` scored against the ``annotation`` (IDF1,
    ID switches, MOTA, recall / precision, tracks per annotated person), its tracks shorter than ``min_track_s`` left
    out: {"people", "detections", "trackers": {name: scores}}, written to ``out``/identities.json beside the MOT
    files it was scored from."""
    *_, evaluate_mot_sequence = trackers_package()
    by_frame, fps, count, layout = load_detections(detections)
    annotated = read_annotation(annotation)
    out.mkdir(parents=True, exist_ok=True)
    truth = out / "truth.txt"
    people = write_truth(by_frame, annotated, truth)
    scores = {}
    for name, found in run_trackers(by_frame, count, fps, layout, camera, video, min_track_s).items():
        path = out / (name.replace(" ", "_").replace("+", "plus") + ".txt")
        path.write_text("".join(_mot_row(f, i, b) for f, rows in sorted(found.items()) for i, b in rows))
        result = evaluate_mot_sequence(truth, path, metrics=["CLEAR", "Identity"])
        tracks = len({i for rows in found.values() for i, _ in rows})
        scores[name] = {"IDF1": round(result.Identity.IDF1, 3), "ID switches": int(result.CLEAR.IDSW),
                        "MOTA": round(result.CLEAR.MOTA, 3), "recall": round(result.CLEAR.CLR_Re, 3),
                        "precision": round(result.CLEAR.CLR_Pr, 3), "tracks": tracks,
                        "tracks per person": round(tracks / max(people, 1), 2)}
    document = {"people": people, "detections": sum(len(v) for v in by_frame.values()), "trackers": scores}
    (out / "identities.json").write_text(json.dumps(document, indent=1))
    return document


def run(job: Job, out: Path, detections: Path | None = None, annotation: Path = ANNOTATION,
        min_track_s: float = VideoOptions().min_track_s) -> dict:
    """The benchmark of the job's one video: its detections by the job's detector (written to
    ``out``/detections.npz; or ``detections`` of an earlier run), then ``compare``."""
    info, camera, finder = video_input(job, 0)
    out.mkdir(parents=True, exist_ok=True)
    if detections is None:
        trackers_package()  # refused before the minutes of detecting, not after them
        detections = detect(info, finder, out / "detections.npz")
    return compare(detections, info.path, camera, out, annotation, min_track_s)


def table(document: dict) -> str:
    """The scores as a markdown table."""
    rows = [f"{document['people']} annotated people; {document['detections']} detections", "",
            "| tracker | IDF1 | ID switches | MOTA | recall / precision | tracks (per person) |",
            "|---|---|---|---|---|---|"]
    rows += [f"| {name} | {s['IDF1']:.3f} | {s['ID switches']} | {s['MOTA']:.3f} | {s['recall']:.3f} / "
             f"{s['precision']:.3f} | {s['tracks']} ({s['tracks per person']}) |"
             for name, s in document["trackers"].items()]
    return "\n".join(rows)
