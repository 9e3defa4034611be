"""How the identities of ``vtest.avi`` were annotated (issue 48; the benchmark itself is ``ray3d bench identity``,
``ray3d.bench.identity``, which ``detect`` and ``compare`` here call).

    python benchmarks/history/vtest_identities.py detect VIDEO --camera CAMERA --out DETECTIONS.npz
    python benchmarks/history/vtest_identities.py review DETECTIONS.npz VIDEO --camera CAMERA --out DIR
    python benchmarks/history/vtest_identities.py annotate DIR/draft.csv --labels LABELS.json --out ANNOTATION.csv
    python benchmarks/history/vtest_identities.py compare DETECTIONS.npz VIDEO --camera CAMERA [--min-track-s 1.0] \\
        --annotation src/ray3d/bench/data/vtest_identities.csv --out DIR

``review`` is the annotation aid: the floor tracker's draft (without re-joins) and the sheets a person labels it
from (each track's life, every meeting of two tracks, every track's start beside the ends before it); ``annotate``
writes the annotation from the draft and the labels; see ``src/ray3d/bench/data/vtest_identities.md`` for how it
was made (the draft labelled and the labels: ``vtest_identities_draft.csv``, ``vtest_identities_labels.json``
here). Needs the video extra and, for ``compare``, the ``trackers`` package.
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import cv2
import numpy as np

from ray3d.bench.identity import compare, detect, floor_tracks, load_detections
from ray3d.jobs import CameraChoice, Job, video_input
from ray3d.lifting.options import VideoOptions
from ray3d.video import read_frames


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
    if args.command == "annotate":
        annotate(args.draft, args.labels, args.out)
        return
    info, camera, finder = video_input(Job((args.video,), (CameraChoice(str(args.camera)),)), 0)
    if args.command == "detect":
        detect(info, finder, args.out)
    elif args.command == "review":
        by_frame, fps, count, layout = load_detections(args.detections)
        tracks = floor_tracks(by_frame, count, fps, layout, camera, args.video)
        write_identities(args.out / "draft.csv", tracks)
        draw_review(tracks, args.video, args.out, fps)
    else:
        print(json.dumps(compare(args.detections, args.video, camera, args.out, args.annotation, args.min_track_s),
                         indent=1))


if __name__ == "__main__":
    main()
