"""Who is who, measured against identities annotated by hand (issue 48): the floor tracker (with its re-joins)
and the maintained trackers of the ``trackers`` package (ByteTrack, OC-SORT, SORT) on the same detections,
scored with the standard multi-object-tracking metrics (IDF1, ID switches, MOTA; the ``trackers`` package's
port of TrackEval).

    python benchmarks/vtest_identities.py detect VIDEO --camera CAMERA --out DETECTIONS.npz
    python benchmarks/vtest_identities.py review DETECTIONS.npz VIDEO --camera CAMERA --out DIR
    python benchmarks/vtest_identities.py annotate DIR/draft.csv --labels LABELS.json --out ANNOTATION.csv
    python benchmarks/vtest_identities.py compare DETECTIONS.npz VIDEO --camera CAMERA [--min-track-s 1.0] \\
        --annotation benchmarks/vtest_identities.csv --out DIR

``detect`` runs ``ray3d video``'s detector (``combined``) over the video once and keeps every detection.
``review`` is the annotation aid: the floor tracker's draft (without re-joins) and the sheets a person labels it
from (each track's life, every meeting of two tracks, every track's start beside the ends before it); ``annotate``
writes the annotation from the draft and the labels; see ``benchmarks/vtest_identities.md`` for how the fixture was
made. ``compare`` scores each tracker against the annotation: a tracker's box is the annotated box it overlaps at
IoU >= 0.5.

Needs the video extra and, for ``compare``, the ``trackers`` package (its pins in constraints.txt; it asks for
opencv-python, which the video extra's OpenCV provides: ``pip install -c constraints.txt --no-deps trackers
supervision pydeprecate defusedxml rich markdown-it-py mdurl pygments requests``).
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from ray3d.io.camera_files import read_camera
from ray3d.lifting.options import VideoOptions
from ray3d.skeleton import BLAZEPOSE33
from ray3d.video import make_detector, read_frames, read_video_info
from ray3d.video.boxes import box_overlap
from ray3d.video.detectors import Detection
from ray3d.video.frames import camera_for_video, spread_frames
from ray3d.video.pipeline import follow_people
from ray3d.video.tracking import CONFIRM_FRAMES, FloorTracker


def detect(video: Path, camera_path: Path, out: Path) -> None:
    """Every detection of the video's frames: frame index, pixels, confidences, person score (one row each)."""
    info = read_video_info(video)
    camera = camera_for_video(read_camera(camera_path), info)
    detector = make_detector("combined", camera)
    detector.prepare(spread_frames(info, 0, info.frames))
    frames, pixels, confidences, scores = [], [], [], []
    for index, frame in tqdm(read_frames(info.path), total=info.frames, unit="frame"):
        for detection in detector(frame):
            frames.append(index)
            pixels.append(detection.pixels)
            confidences.append(detection.confidences)
            scores.append(detection.score)
    np.savez_compressed(out, frames=np.array(frames), pixels=np.array(pixels), confidences=np.array(confidences),
                        scores=np.array(scores), fps=info.fps, frame_count=info.frames)
    print(f"{len(frames)} detections in {info.frames} frames -> {out}")


def load_detections(path: Path) -> tuple[dict[int, list[Detection]], float, int]:
    """{frame: its detections}, the frame rate and the frame count of a ``detect`` file."""
    data = np.load(path)
    by_frame: dict[int, list[Detection]] = {i: [] for i in range(int(data["frame_count"]))}
    for frame, pixels, confidences, score in zip(data["frames"], data["pixels"], data["confidences"], data["scores"]):
        by_frame[int(frame)].append(Detection(pixels, confidences, float(score)))
    return by_frame, float(data["fps"]), int(data["frame_count"])


def floor_tracks(by_frame: dict[int, list[Detection]], frame_count: int, fps: float, camera, video: Path) -> list:
    """``ray3d video``'s floor tracker's tracks of these detections (before its re-joins)."""
    tracker = FloorTracker(camera, fps, BLAZEPOSE33.name, VideoOptions().max_gap_s, CONFIRM_FRAMES)
    for index, frame in read_frames(video, 0, frame_count):
        tracker.update(index, by_frame[index], frame)
    return tracker.tracks()


def meetings(tracks, apart_frames: int = 10) -> list[tuple[int, int, str, str]]:
    """(first frame, last frame, track a, track b) wherever two tracks' boxes come within half a person's height
    of each other (centres, across and down): where a tracker may swap them (meetings of a pair less than
    ``apart_frames`` apart are one)."""
    boxes: dict[int, list] = {}
    for track in tracks:
        for frame, detection in zip(track.frames, track.detections):
            boxes.setdefault(frame, []).append((track.id, detection.box))
    close: dict[tuple[str, str], list[int]] = {}
    for frame, present in boxes.items():
        for a, (id_a, box_a) in enumerate(present):
            for id_b, box_b in present[a + 1:]:
                height = max(box_a[3] - box_a[1], box_b[3] - box_b[1])
                if (np.abs((box_a[:2] + box_a[2:]) / 2 - (box_b[:2] + box_b[2:]) / 2) < height / 2).all():
                    close.setdefault(tuple(sorted((id_a, id_b))), []).append(frame)
    found = []
    for (id_a, id_b), frames in close.items():
        frames = sorted(frames)
        first = frames[0]
        for this, following in zip(frames, frames[1:] + [None]):
            if following is None or following - this > apart_frames:
                found.append((first, this, id_a, id_b))
                first = following
    return sorted(found)


def draw_review(tracks, video: Path, out: Path, fps: float) -> None:
    """The sheets a person reviews the draft identities on (see ``benchmarks/vtest_identities.md``): each
    track's life in 10 crops; each meeting of two tracks, both before and after; each track's start beside the
    last crops of the tracks that ended within 3 s before it."""
    out.mkdir(parents=True, exist_ok=True)
    images = dict(read_frames(video))
    at = {t.id: dict(zip(t.frames, t.detections)) for t in tracks}

    def crop(track_id: str, frame: int, text: str) -> np.ndarray:
        frames = np.array(sorted(at[track_id]))
        nearest = int(frames[np.argmin(np.abs(frames - frame))])
        return _label(_crop(images[nearest], at[track_id][nearest].box), f"{track_id}", f"{text}{nearest}")

    gap = np.full((120, 10, 3), 255, np.uint8)
    found_meetings = meetings(tracks)
    lives = []
    for track in tracks:  # each stretch between meetings: its first and last crops (a swap shows between them)
        cuts = {track.frames[0], track.frames[-1]}
        for first, last, a, b in found_meetings:
            if track.id in (a, b):
                cuts |= set(range(first, last + 1, 20)) | {last}
        tiles = []
        for frame in sorted(cuts):
            tiles += [crop(track.id, frame, ""), gap[:, :3]]
        for row in range(0, len(tiles), 16):
            lives.append(np.hstack(tiles[row:row + 16]))
    second = int(round(fps))
    meets = [np.hstack([crop(a, first - second, "<"), crop(a, last + second, ">"), gap,
                        crop(b, first - second, "<"), crop(b, last + second, ">")])
             for first, last, a, b in found_meetings]
    starts = []
    for track in tracks:
        ended = sorted((t for t in tracks if track.frames[0] - 3 * fps <= t.frames[-1] < track.frames[0]),
                       key=lambda t: -t.frames[-1])[:7]
        starts.append(np.hstack([crop(track.id, track.frames[0], "s"), gap] +
                                [crop(t.id, t.frames[-1], "e") for t in ended]))
    for name, rows in (("lives", lives), ("meetings", meets), ("starts", starts)):
        width = max(r.shape[1] for r in rows)
        rows = [np.hstack([r, np.zeros((120, width - r.shape[1], 3), np.uint8)]) for r in rows]
        for sheet in range(0, len(rows), 10):
            cv2.imwrite(str(out / f"{name}-{sheet // 10:02d}.png"), np.vstack(rows[sheet:sheet + 10]))
    (out / "meetings.json").write_text(json.dumps(found_meetings))


def annotate(draft: Path, labels: Path, out: Path) -> None:
    """The annotation: each draft row's track relabelled with the person ``labels`` say it is from that frame
    on (rows whose label is null left out); refused where one person would be in two boxes of one frame."""
    spans = json.loads(labels.read_text())["tracks"]
    rows, seen = [], set()
    with open(draft, newline="") as stream:
        for row in csv.DictReader(stream):
            frame = int(row["frame"])
            person = [who for first, who in spans[row["person"]] if first <= frame][-1]
            if person is None:
                continue
            if (frame, person) in seen:
                raise SystemExit(f"{labels}: {person} twice in frame {frame}")
            seen.add((frame, person))
            rows.append({**row, "person": person})
    with open(out, "w", newline="") as stream:
        writer = csv.DictWriter(stream, ["frame", "person", "x0", "y0", "x1", "y1"])
        writer.writeheader()
        writer.writerows(sorted(rows, key=lambda r: (int(r["frame"]), r["person"])))
    print(f"{len(rows)} annotated boxes of {len({r['person'] for r in rows})} people -> {out}")


def _mot_rows(frame: int, identity: int, box, kind: int = 1) -> str:
    """One MOT-challenge line: frame (from 1), id, left, top, width, height, conf, class."""
    x0, y0, x1, y1 = box
    return f"{frame + 1},{identity},{x0:.1f},{y0:.1f},{x1 - x0:.1f},{y1 - y0:.1f},1,{kind},1\n"


def write_truth(by_frame: dict[int, list[Detection]], annotation: Path, path: Path) -> None:
    """The annotation as MOT ground truth: each annotated box a pedestrian with its person's number; every
    detection that overlaps no annotated box at IoU >= 0.5 a distractor (class 8: a tracker's box on it is neither
    right nor wrong). By overlap, not equality: the annotation's boxes are one detector's, and another detector's
    box on an annotated person must count for them, not be discarded as a distractor."""
    people: dict[str, int] = {}
    annotated: dict[int, list[tuple[int, np.ndarray]]] = {}
    with open(annotation, newline="") as stream:
        for row in csv.DictReader(stream):
            number = people.setdefault(row["person"], len(people) + 1)
            box = np.array([float(row[k]) for k in ("x0", "y0", "x1", "y1")])
            annotated.setdefault(int(row["frame"]), []).append((number, box))
    lines, distractor = [], 10_000
    for frame, detections in by_frame.items():
        boxes = annotated.get(frame, [])
        lines += [_mot_rows(frame, number, box) for number, box in boxes]
        for detection in detections:
            if not boxes or box_overlap(detection.box[None], np.stack([box for _, box in boxes])).max() < 0.5:
                distractor += 1
                lines.append(_mot_rows(frame, distractor, detection.box, kind=8))
    path.write_text("".join(lines))


def run_trackers(by_frame, frame_count: int, fps: float, camera, video: Path,
                 min_track_s: float) -> dict[str, dict[int, list]]:
    """{tracker: {frame: [(track id, box)]}}: the floor tracker with and without its re-joins, and the
    ``trackers`` package's ByteTrack, OC-SORT and SORT at their defaults (given the video's frame rate), all on
    the same detections (boxes of the confident joints, the landmark network's person score); every tracker's
    tracks followed for less than ``min_track_s`` left out, as ``ray3d video`` leaves out its own."""
    import supervision as sv
    from trackers import ByteTrackTracker, OCSORTTracker, SORTTracker

    results: dict[str, dict[int, list]] = {}
    tracks = floor_tracks(by_frame, frame_count, fps, camera, video)
    for name, rejoin_s in (("floor tracker + re-join", VideoOptions().rejoin_s), ("floor tracker", 0.0)):
        found = results[name] = {}
        options = VideoOptions(rejoin_s=rejoin_s, min_track_s=min_track_s)
        for number, track in enumerate(follow_people(tracks, fps, frame_count, options).kept):
            for frame, detection in zip(track.frames, track.detections):
                found.setdefault(frame, []).append((number + 1, detection.box))
    for name, tracker in (("ByteTrack", ByteTrackTracker(frame_rate=fps)), ("OC-SORT", OCSORTTracker(frame_rate=fps)),
                          ("SORT", SORTTracker(frame_rate=fps))):
        found = results[name] = {}
        for frame in range(frame_count):
            detections = by_frame[frame]
            boxes = np.array([d.box for d in detections], dtype=np.float32).reshape(-1, 4)
            given = sv.Detections(xyxy=boxes, confidence=np.array([d.score for d in detections], dtype=np.float32),
                                  class_id=np.zeros(len(detections), dtype=int))
            tracked = tracker.update(given)
            found[frame] = [(int(i) + 1, box) for i, box in zip(tracked.tracker_id, tracked.xyxy) if i >= 0]
        results[name] = _without_short_tracks(found, fps, min_track_s)
    return results


def _without_short_tracks(found: dict[int, list], fps: float, min_track_s: float) -> dict[int, list]:
    """A tracker's {frame: [(track id, box)]} less the tracks followed (first to last frame) for less than
    ``min_track_s``: the rule of ``ray3d.video.pipeline.follow_people``, on a maintained tracker's tracks."""
    frames: dict[int, list[int]] = {}
    for frame, rows in found.items():
        for identity, _ in rows:
            frames.setdefault(identity, []).append(frame)
    short = {i for i, seen in frames.items() if (max(seen) - min(seen) + 1) / fps < min_track_s}
    return {frame: [(i, box) for i, box in rows if i not in short] for frame, rows in found.items()}


def compare(detections: Path, camera_path: Path, video: Path, annotation: Path, out: Path,
            min_track_s: float) -> None:
    """Each tracker scored against the annotation (IDF1, ID switches, MOTA, recall / precision, tracks per
    annotated person), its tracks shorter than ``min_track_s`` left out, printed as a table and written to
    ``out``/identities.json."""
    from trackers.eval import evaluate_mot_sequence

    by_frame, fps, count = load_detections(detections)
    out.mkdir(parents=True, exist_ok=True)
    truth = out / "truth.txt"
    write_truth(by_frame, annotation, truth)
    people = {line.split(",")[1] for line in truth.read_text().splitlines() if line.split(",")[7] == "1"}
    scores = {}
    found_by = run_trackers(by_frame, count, fps, read_camera(camera_path), video, min_track_s)
    for name, found in found_by.items():
        path = out / (name.replace(" ", "_").replace("+", "plus") + ".txt")
        path.write_text("".join(_mot_rows(f, i, b) for f, rows in sorted(found.items()) for i, b in rows))
        result = evaluate_mot_sequence(truth, path, metrics=["CLEAR", "Identity"])
        tracks = len({i for rows in found.values() for i, _ in rows})
        scores[name] = {"IDF1": round(result.Identity.IDF1, 3), "ID switches": int(result.CLEAR.IDSW),
                        "MOTA": round(result.CLEAR.MOTA, 3), "recall": round(result.CLEAR.CLR_Re, 3),
                        "precision": round(result.CLEAR.CLR_Pr, 3), "tracks": tracks,
                        "tracks per person": round(tracks / len(people), 2)}
    print(f"{len(people)} annotated people; {sum(len(v) for v in by_frame.values())} detections")
    print("| tracker | IDF1 | ID switches | MOTA | recall / precision | tracks (per person) |\n"
          "|---|---|---|---|---|---|")
    for name, s in scores.items():
        print(f"| {name} | {s['IDF1']:.3f} | {s['ID switches']} | {s['MOTA']:.3f} | {s['recall']:.3f} / "
              f"{s['precision']:.3f} | {s['tracks']} ({s['tracks per person']}) |")
    (out / "identities.json").write_text(json.dumps(scores, indent=1))


def write_identities(path: Path, tracks) -> None:
    """frame, person, x0, y0, x1, y1 (the detection's box: its confident joints) for every tracked detection."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as stream:
        rows = csv.writer(stream)
        rows.writerow(["frame", "person", "x0", "y0", "x1", "y1"])
        for track in tracks:
            for frame, detection in zip(track.frames, track.detections):
                rows.writerow([frame, track.id, *np.round(detection.box, 1).tolist()])


def _crop(frame: np.ndarray, box: np.ndarray, height: int = 120, width: int = 84) -> np.ndarray:
    """The person's box drawn on the frame around it (a margin of a third of its height), scaled to ``height``
    px, cut or padded to ``width`` about the box (BGR)."""
    x0, y0, x1, y1 = box
    margin = (y1 - y0) / 3
    rows, cols = frame.shape[:2]
    u0, u1 = int(max(0, x0 - margin)), int(min(cols, x1 + margin))
    v0, v1 = int(max(0, y0 - margin / 2)), int(min(rows, y1 + margin / 2))
    patch = np.ascontiguousarray(frame[v0:max(v1, v0 + 2), u0:max(u1, u0 + 2)])
    scale = height / patch.shape[0]
    patch = cv2.resize(patch, (max(8, int(patch.shape[1] * scale)), height))
    cv2.rectangle(patch, (int((x0 - u0) * scale), int((y0 - v0) * scale)), (int((x1 - u0) * scale),
                  int((y1 - v0) * scale)), (255, 255, 0), 1)
    sides = max(0, width - patch.shape[1])
    patch = cv2.copyMakeBorder(patch, 0, 0, sides // 2, sides - sides // 2, cv2.BORDER_CONSTANT)
    centre = int(((x0 + x1) / 2 - u0) * scale) + sides // 2
    start = int(np.clip(centre - width // 2, 0, patch.shape[1] - width))
    return cv2.cvtColor(np.ascontiguousarray(patch[:, start:start + width]), cv2.COLOR_RGB2BGR)


def _label(tile: np.ndarray, top: str, bottom: str) -> np.ndarray:
    tile = tile.copy()
    tile[:14], tile[-14:] = 0, 0
    cv2.putText(tile, top, (1, 11), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (0, 255, 255), 1)
    cv2.putText(tile, bottom, (1, 117), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (255, 255, 255), 1)
    return tile


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    commands = {"detect": (["video"], ["camera", "out"]), "review": (["detections", "video"], ["camera", "out"]),
                "annotate": (["draft"], ["labels", "out"]),
                "compare": (["detections", "video"], ["camera", "annotation", "out"])}
    for name, (positional, required) in commands.items():
        command = sub.add_parser(name)
        for field in positional:
            command.add_argument(field, type=Path)
        for field in required:
            command.add_argument(f"--{field}", type=Path, required=True)
        if name == "compare":
            command.add_argument("--min-track-s", type=float, default=VideoOptions().min_track_s,
                                 help="leave out every tracker's tracks followed for less (ray3d video's default; "
                                      "0: keep all)")
    args = parser.parse_args()
    if args.command == "detect":
        detect(args.video, args.camera, args.out)
    elif args.command == "review":
        by_frame, fps, count = load_detections(args.detections)
        camera = read_camera(args.camera)
        tracks = floor_tracks(by_frame, count, fps, camera, args.video)
        write_identities(args.out / "draft.csv", tracks)
        draw_review(tracks, args.video, args.out, fps)
    elif args.command == "annotate":
        annotate(args.draft, args.labels, args.out)
    else:
        compare(args.detections, args.camera, args.video, args.annotation, args.out, args.min_track_s)


if __name__ == "__main__":
    main()
