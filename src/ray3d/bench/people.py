"""Everyone in view (``ray3d bench people``): how many of the people in view ``ray3d video``'s detector finds, by the
way they face, how crowded, partly hidden and how tall, against a hand-made annotation, for each full-frame
finder, with the detector's time per frame.

The annotation shipped (``ANNOTATION``): 60 people in 10 frames of ``vtest.avi``, each a full-body box, the way they
face and whether something hides part of them (how it was made: its ``what``). A person is found where a
detection's box (its confident keypoints, grown to the head's top and the soles) overlaps theirs at ``MATCH_IOU`` or
more, each detection matched to one person at most; "loosely" where its centre lies in their box and its height is
0.6-1.5 times theirs (the annotation's boxes are MoveNet's, of another shape than a pose's). Every frame of the video
is run (the detector follows people from frame to frame); the annotated ones are scored. Needs the video extra."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from ray3d.errors import InputError
from ray3d.jobs import CameraChoice, Job, video_input
from ray3d.video import read_frames
from ray3d.video.boxes import box_inside, box_overlap, matched_one_to_one, whole_person
from ray3d.video.detectors import EMPTY_EVERY, PeopleDetector
from ray3d.video.frames import spread_frames
from ray3d.video.movenet import MoveNetPeople

ANNOTATION = Path(__file__).parent / "data" / "vtest_people.json"
FINDER_NAMES = "none, or movenet-SIZE[-COLUMNSxROWS] (its input in pixels, the frame cut into tiles): movenet-384-2x1"
MATCH_IOU = 0.5
LOOSE_HEIGHTS = (0.6, 1.5)  # a loosely found person's box height over theirs
CROWDED = 0.1  # a person's box this much inside another's: crowded
HEIGHTS = ((0, 80), (80, 120), (120, 10_000))  # bands of a person's height in the picture, pixels


def read_annotation(path: Path) -> dict[int, list[dict]]:
    """{frame: its annotated people (box, facing, partly_hidden)} of an annotation file."""
    try:
        return {int(f["frame"]): f["people"] for f in json.loads(Path(path).read_text())["frames"]}
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise InputError(f"{path}: not an annotation of people in view (frames: frame, people): {error}") from None


def splits(people: list[dict]) -> list[list[str]]:
    """Each annotated person's splits: facing, crowded (their box overlapping another person's), partly hidden,
    height band."""
    boxes = np.array([p["box"] for p in people], dtype=float)
    out = []
    for i, person in enumerate(people):
        crowded = any(box_inside(boxes[i], boxes[j]) > CROWDED for j in range(len(people)) if j != i)
        tall = boxes[i, 3] - boxes[i, 1]
        band = next(f"{low}-{high} px" if high < 10_000 else f"{low}+ px" for low, high in HEIGHTS
                    if low <= tall < high)
        out.append(["all", f"facing {person['facing']}", "crowded" if crowded else "apart",
                    *(["partly hidden"] if person["partly_hidden"] else []), band])
    return out


def found(people: list[dict], detections: list, loose: bool = False) -> np.ndarray:
    """(N,) whether each annotated person was found (one detection each at most): its whole-person box overlapping
    theirs by ``MATCH_IOU``, or, ``loose``, its centre inside theirs and its height ``LOOSE_HEIGHTS`` times theirs."""
    truth = np.array([p["box"] for p in people], dtype=float)
    if not detections:
        return np.zeros(len(people), bool)
    boxes = whole_person(np.array([d.box for d in detections]))
    overlap = box_overlap(truth, boxes)
    if loose:
        centre = (boxes[:, :2] + boxes[:, 2:]) / 2
        inside = ((centre[None] >= truth[:, None, :2]) & (centre[None] <= truth[:, None, 2:])).all(-1)
        ratio = (boxes[None, :, 3] - boxes[None, :, 1]) / (truth[:, None, 3] - truth[:, None, 1])
        overlap = np.where(inside & (ratio >= LOOSE_HEIGHTS[0]) & (ratio <= LOOSE_HEIGHTS[1]), 1.0, 0.0)
    return matched_one_to_one(overlap, MATCH_IOU)


def finder_named(name: str) -> MoveNetPeople | None:
    """The full-frame finder a name stands for (``FINDER_NAMES``)."""
    if name == "none":
        return None
    parts = name.split("-")
    tiles = parts[2].split("x") if len(parts) == 3 else ["1", "1"]
    if not (len(parts) in (2, 3) and parts[0] == "movenet" and parts[1].isdigit() and len(tiles) == 2
            and all(n.isdigit() for n in tiles)):
        raise InputError(f"--finders: {name!r} is not {FINDER_NAMES}")
    return MoveNetPeople(2, int(parts[1]), (int(tiles[0]), int(tiles[1])))


def run(video: Path, camera: str, finder: str, annotated: dict[int, list[dict]], every: int = 1) -> dict:
    """``video`` (seen by ``camera``) through ``ray3d video``'s detector with the full-frame ``finder`` on every
    ``every``-th frame: {"finder", "every", "frames_per_s" (the detector's), "recall": {split: (found, people)}}."""
    found_whole = finder_named(finder)
    job = Job((video,), (CameraChoice(camera),),  # stale motion looked at less where a finder looks in between
              detector=lambda made: PeopleDetector(made, finder=found_whole, full_frame_every=every,
                                                   empty_every=1 if found_whole is None else EMPTY_EVERY))
    info, _, detector = video_input(job, 0)
    detector.prepare(spread_frames(info, 0, info.frames))
    tally: dict[str, list[int]] = {}
    seconds, frames = 0.0, 0
    for index, frame in read_frames(info.path):
        started = time.perf_counter()
        detections = detector(frame)
        seconds, frames = seconds + time.perf_counter() - started, frames + 1
        if index not in annotated:
            continue
        people = annotated[index]
        for split_names, hit, loose in zip(splits(people), found(people, detections), found(people, detections, True)):
            for name in split_names + ["all, loosely"] * (split_names[0] == "all"):
                tally.setdefault(name, [0, 0])
                tally[name][0] += int(loose if name == "all, loosely" else hit)
                tally[name][1] += 1
    return {"finder": finder, "every": every, "frames_per_s": round(frames / max(seconds, 1e-9), 1),
            "recall": {name: tuple(counts) for name, counts in sorted(tally.items())}}


def row_line(row: dict) -> str:
    """One finder's row of ``run`` as a line: its rate and each split's people found of those annotated."""
    cells = "  ".join(f"{name} {hits}/{total}" for name, (hits, total) in row["recall"].items())
    return f"{row['finder']:16s} {row['frames_per_s']:5.1f} frames/s  {cells}"
