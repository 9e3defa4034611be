"""How many of the people in view ray3d's video detector finds, by the way they face, how crowded, partly hidden
and how tall, against a hand-made annotation (``benchmarks/annotations/vtest_people.json``: 60 people in 10 frames
of ``vtest.avi``), for each full-frame finder, with the time per frame.

    python benchmarks/person_finder.py --video ../shared/data/real-video/vtest.avi \
        --camera ../shared/data/real-video/vtest_camera.json [--finders none blazepose movenet-384 ...]

A person is found where a detection's box (its confident keypoints, grown to the head's top and the soles: the
keypoints stop at the eyes and ankles) overlaps theirs by 0.5 or more (intersection over union), each detection
matched to one person at most; "loosely" where its centre lies in their box and its height is 0.6-1.5 times theirs
(the annotation's boxes are MoveNet's, of another shape than a pose's). Every frame of the video is run (the detector
follows people from frame to frame); the annotated ones are scored. Needs the video extra.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment

from ray3d.io.camera_files import read_camera
from ray3d.video.boxes import box_inside, box_overlap, whole_person
from ray3d.video.detectors import PeopleDetector
from ray3d.video.movenet import MoveNetPeople

ANNOTATION = Path(__file__).parent / "annotations" / "vtest_people.json"
FINDER_NAMES = "none, or movenet-SIZE[-COLUMNSxROWS] (its input in pixels, the frame cut into tiles): movenet-384-2x1"
MATCH = 0.5
HEIGHTS = ((0, 80), (80, 120), (120, 10_000))  # pixels


def splits(people: list[dict]) -> list[list[str]]:
    """Each annotated person's splits: facing, crowded (their box overlapping another person's), partly hidden,
    height band."""
    boxes = np.array([p["box"] for p in people], dtype=float)
    out = []
    for i, person in enumerate(people):
        crowded = any(box_inside(boxes[i], boxes[j]) > 0.1 for j in range(len(people)) if j != i)
        tall = boxes[i, 3] - boxes[i, 1]
        band = next(f"{low}-{high} px" if high < 10_000 else f"{low}+ px" for low, high in HEIGHTS
                    if low <= tall < high)
        out.append(["all", f"facing {person['facing']}", "crowded" if crowded else "apart",
                    *(["partly hidden"] if person["partly_hidden"] else []), band])
    return out


def found(people: list[dict], detections: list, loose: bool = False) -> np.ndarray:
    """(N,) whether each annotated person was found (one detection each at most): its whole-person box overlapping
    theirs by ``MATCH``, or, ``loose``, its centre inside theirs and its height 0.6-1.5 times theirs (found, with a
    box of another shape: the annotation's boxes are the finders' own)."""
    truth = np.array([p["box"] for p in people], dtype=float)
    if not detections:
        return np.zeros(len(people), bool)
    boxes = whole_person(np.array([d.box for d in detections]))
    overlap = box_overlap(truth, boxes)
    if loose:
        centre = (boxes[:, :2] + boxes[:, 2:]) / 2
        inside = ((centre[None] >= truth[:, None, :2]) & (centre[None] <= truth[:, None, 2:])).all(-1)
        ratio = (boxes[None, :, 3] - boxes[None, :, 1]) / (truth[:, None, 3] - truth[:, None, 1])
        overlap = np.where(inside & (ratio >= 0.6) & (ratio <= 1.5), 1.0, 0.0)
    rows, columns = linear_sum_assignment(-overlap)
    hit = np.zeros(len(people), bool)
    hit[rows[overlap[rows, columns] >= MATCH]] = True
    return hit


def finder_named(name: str) -> MoveNetPeople | None:
    """The finder a name stands for (``FINDER_NAMES``)."""
    if name == "none":
        return None
    parts = name.split("-")
    if len(parts) not in (2, 3) or parts[0] != "movenet" or not parts[1].isdigit():
        raise SystemExit(f"--finders: {name!r} is not {FINDER_NAMES}")
    columns, rows = (int(n) for n in parts[2].split("x")) if len(parts) == 3 else (1, 1)
    return MoveNetPeople(2, int(parts[1]), (columns, rows))


def run(video: str, camera_path: str, finder: str, annotation: dict, every: int = 1) -> dict:
    camera = read_camera(camera_path)
    capture, frames = cv2.VideoCapture(video), []
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        frames.append(cv2.cvtColor(frame, cv2.COLOR_BGR2RGB))
    detector = PeopleDetector(camera, finder=finder_named(finder), full_frame_every=every)
    detector.prepare([frames[i] for i in np.linspace(0, len(frames) - 1, 25).astype(int)])
    wanted = {f["frame"]: f["people"] for f in annotation["frames"]}
    tally: dict[str, list[int]] = {}
    started = time.perf_counter()
    for index, frame in enumerate(frames):
        detections = detector(frame)
        if index in wanted:
            loosely = found(wanted[index], detections, loose=True)
            for split_names, hit, loose in zip(splits(wanted[index]), found(wanted[index], detections), loosely):
                for name in split_names + ["all, loosely"] * (split_names[0] == "all"):
                    tally.setdefault(name, [0, 0])
                    tally[name][0] += int(loose if name == "all, loosely" else hit)
                    tally[name][1] += 1
    seconds = time.perf_counter() - started
    return {"finder": finder, "every": every, "frames_per_s": len(frames) / seconds,
            "recall": {name: (hits, total) for name, (hits, total) in sorted(tally.items())}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--video", required=True)
    parser.add_argument("--camera", required=True)
    parser.add_argument("--annotation", default=str(ANNOTATION))
    parser.add_argument("--finders", nargs="+", default=["none", "movenet-384", "movenet-384-2x1"],
                        help=FINDER_NAMES)
    parser.add_argument("--finder-every", type=int, default=1, help="the finder on every n-th frame only")
    parser.add_argument("--out", help="write the rows as JSON here")
    args = parser.parse_args()
    annotation = json.loads(Path(args.annotation).read_text())
    rows = []
    for finder in args.finders:
        row = run(args.video, args.camera, finder, annotation, args.finder_every)
        rows.append(row)
        cells = "  ".join(f"{name} {hits}/{total}" for name, (hits, total) in row["recall"].items())
        print(f"{finder:16s} {row['frames_per_s']:5.1f} frames/s  {cells}", flush=True)
    if args.out:
        Path(args.out).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
