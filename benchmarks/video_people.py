"""Several people in a video, measured: runs ``ray3d video``'s pipeline on a video with its camera, records the
speed of each stage and the peak memory, and draws frames spread over the clip with every person found (the
box around their detected joints and their track id) for counting by hand (visible people vs found).

    python benchmarks/video_people.py VIDEO --camera CAMERA.json --out DIR [--count-frames 32]

Writes DIR/run/ (the outputs of ``ray3d video``), DIR/count/sheet-*.png (four numbered frames each),
DIR/crossings/*.png (each time one person passes another in the image: the overlay before, at and after, to
judge whether the ids stayed with their people) and DIR/video-people.json (timings, memory, tracks,
detections per counted frame, crossings)."""

from __future__ import annotations

import argparse
import json
import resource
from pathlib import Path

import cv2
import numpy as np

from ray3d.io.camera_files import read_camera
from ray3d.jobs import load_lifter
from ray3d.video import lift_video, make_detector, read_frames, read_video_info


def count_sheets(video: Path, keypoints, frames: list[int], out_dir: Path, rows_shown=(0, None)) -> dict[int, int]:
    """Draw the found people on each of ``frames`` (image rows ``rows_shown`` of them: where people can be);
    2 x 2 frames per sheet. Returns {frame: people found}."""
    out_dir.mkdir(parents=True, exist_ok=True)
    found, tiles = {}, []
    for index in frames:
        frame = next(read_frames(video, index, 1))[1]
        canvas = cv2.cvtColor(frame, cv2.COLOR_RGB2BGR)
        rows = np.flatnonzero(keypoints.frames == index)
        for row in rows:
            seen = keypoints.pixels[row][keypoints.confidences[row] >= 0.5]
            (x0, y0), (x1, y1) = seen.min(axis=0).astype(int), seen.max(axis=0).astype(int)
            cv2.rectangle(canvas, (x0, y0), (x1, y1), (0, 255, 0), 1)
            cv2.putText(canvas, str(keypoints.tracks[row]), (x0, y0 - 3), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                        (0, 255, 255), 1)
        cv2.putText(canvas, f"frame {index}: {len(rows)} found", (10, (rows_shown[0] or 0) + 25),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.8, (0, 255, 255), 2)
        found[index] = len(rows)
        tiles.append(canvas[rows_shown[0]:rows_shown[1]])
    for sheet in range(0, len(tiles), 4):
        group = tiles[sheet:sheet + 4] + [np.zeros_like(tiles[0])] * (4 - len(tiles[sheet:sheet + 4]))
        image = np.vstack([np.hstack(group[:2]), np.hstack(group[2:])])
        cv2.imwrite(str(out_dir / f"sheet-{sheet // 4:02d}.png"), image)
    return found


def crossings(keypoints, min_gap_frames: int = 20) -> list[tuple[int, str, str]]:
    """(frame, track a, track b) where two people's boxes overlap in the image (one passes in front of the
    other), the first frame of each such meeting (meetings of the same pair closer than ``min_gap_frames``
    count once)."""
    boxes = {}
    for row, (frame, track) in enumerate(zip(keypoints.frames, keypoints.tracks)):
        seen = keypoints.pixels[row][keypoints.confidences[row] >= 0.5]
        if len(seen) >= 2:
            boxes.setdefault(int(frame), []).append((str(track), *seen.min(axis=0), *seen.max(axis=0)))
    events, last = [], {}
    for frame in sorted(boxes):
        people = boxes[frame]
        for i, (a, ax0, ay0, ax1, ay1) in enumerate(people):
            for b, bx0, by0, bx1, by1 in people[i + 1:]:
                overlap = min(ax1, bx1) - max(ax0, bx0)
                if overlap > 0.5 * min(ax1 - ax0, bx1 - bx0) and min(ay1, by1) > max(ay0, by0):
                    pair = tuple(sorted((a, b)))
                    if frame - last.get(pair, -10 ** 9) > min_gap_frames:
                        events.append((frame, *pair))
                    last[pair] = frame
    return events


def crossing_sheets(overlay: Path, keypoints, events, out_dir: Path, offset: int = 8) -> None:
    """For each crossing, the overlay frames ``offset`` before, at and after it, cropped around the pair."""
    out_dir.mkdir(parents=True, exist_ok=True)
    for number, (frame, a, b) in enumerate(events):
        rows = np.flatnonzero((keypoints.frames == frame) & np.isin(keypoints.tracks.astype(str), [a, b]))
        seen = keypoints.pixels[rows].reshape(-1, 2)
        (x0, y0), (x1, y1) = seen.min(axis=0), seen.max(axis=0)
        cx, cy, half = (x0 + x1) / 2, (y0 + y1) / 2, max(x1 - x0, y1 - y0) * 0.9 + 40
        tiles = []
        for index in (frame - offset, frame, frame + offset):
            found = next(read_frames(overlay, max(index, 0), 1), None)
            if found is None:
                continue
            image = cv2.cvtColor(found[1], cv2.COLOR_RGB2BGR)
            u0, v0 = int(max(cx - half, 0)), int(max(cy - half, 0))
            crop = image[v0:int(cy + half), u0:int(cx + half)]
            crop = cv2.resize(crop, (300, int(300 * crop.shape[0] / max(crop.shape[1], 1))))
            cv2.putText(crop, str(index), (5, 15), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 255, 255), 1)
            tiles.append(crop)
        height = max(t.shape[0] for t in tiles)
        tiles = [np.pad(t, ((0, height - t.shape[0]), (0, 2), (0, 0))) for t in tiles]
        cv2.imwrite(str(out_dir / f"crossing-{number:02d}-frame{frame}-{a}-{b}.png"), np.hstack(tiles))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("video", type=Path)
    parser.add_argument("--camera", required=True)
    parser.add_argument("--out", required=True, type=Path)
    parser.add_argument("--checkpoint", default="ray3d-real")
    parser.add_argument("--count-frames", type=int, default=32)
    parser.add_argument("--rows", type=int, nargs=2, default=(0, None), metavar=("FIRST", "LAST"),
                        help="image rows to show on the counting sheets (default all)")
    args = parser.parse_args()
    camera = read_camera(args.camera)
    result = lift_video(args.video, camera, args.out / "run", make_detector("people", camera),
                        load_lifter(args.checkpoint), overwrite=True)
    info = read_video_info(args.video)
    counted = np.linspace(5, info.frames - 5, args.count_frames).round().astype(int).tolist()
    found = count_sheets(args.video, result.keypoints, counted, args.out / "count", tuple(args.rows))
    events = crossings(result.keypoints)
    crossing_sheets(result.files["overlay"], result.keypoints, events, args.out / "crossings")
    total = sum(result.seconds.values())
    summary = {
        "frames": result.frames, "seconds": result.seconds, "frames_per_s_end_to_end": result.frames / total,
        "frames_per_s_people": result.frames / result.seconds["people"],
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "tracks": len(result.world.tracks), "dropped": len(result.dropped),
        "detections": int(len(result.keypoints.frames)), "found_in_counted_frames": found,
        "crossings": [list(e) for e in events],
    }
    (args.out / "video-people.json").write_text(json.dumps(summary, indent=1))
    print(json.dumps({k: v for k, v in summary.items() if k != "found_in_counted_frames"}, indent=1))


if __name__ == "__main__":
    main()
