"""Aids for counting line crossings by hand in a fixed camera's video (how the vtest.avi hand count in
docs/RESULTS.md was made): for an image line (two pixels), a slit-scan picture (time across, the line's pixels
down; red: change just left of the line, green: just right of it, so a crossing shows as a streak and its colour
order gives its direction) and, for the frame numbers given, rows of crops at -1.0, -0.5, 0, +0.5, +1.0 s with the
line drawn, to watch each crossing and read its direction. Nothing here reads ray3d's output.

    python benchmarks/hand_count_sheets.py VIDEO --line 400,150,330,310 --out DIR [--frames 12,60,100]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("video", type=Path)
    parser.add_argument("--line", required=True, help="x0,y0,x1,y1 in pixels")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--frames", default="", help="frame numbers to show in crops, comma separated")
    parser.add_argument("--box", default=None, help="crop x0,y0,x1,y1 (default: 100 px around the line)")
    args = parser.parse_args()
    x0, y0, x1, y1 = (int(v) for v in args.line.split(","))
    capture, frames = cv2.VideoCapture(str(args.video)), []
    while (read := capture.read())[0]:
        frames.append(read[1])
    video = np.stack(frames)
    fps = capture.get(cv2.CAP_PROP_FPS) or 10.0
    args.out.mkdir(parents=True, exist_ok=True)
    length = int(np.hypot(x1 - x0, y1 - y0))
    along = np.linspace(0, 1, length)[:, None] * [x1 - x0, y1 - y0] + [x0, y0]
    slit = np.zeros((length, len(video), 3), np.uint8)
    for channel, shift in ((2, -10), (1, 10)):  # BGR: red left of the line, green right of it
        xs = np.clip((along[:, 0] + shift).round().astype(int), 0, video.shape[2] - 1)
        strip = video[:, along[:, 1].round().astype(int), xs].astype(np.float32)
        slit[..., channel] = np.clip(3 * np.abs(strip - np.median(strip, axis=0)).max(-1), 0, 255).T
    slit = cv2.resize(slit, (2 * len(video), 2 * length), interpolation=cv2.INTER_NEAREST)
    for t in range(0, len(video), 50):
        cv2.putText(slit, str(t), (2 * t + 2, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1)
    cv2.imwrite(str(args.out / "slit.png"), slit)
    box = [int(v) for v in args.box.split(",")] if args.box else \
        [max(min(x0, x1) - 100, 0), max(min(y0, y1) - 20, 0), max(x0, x1) + 100, max(y0, y1) + 20]
    rows = []
    for t in (int(v) for v in args.frames.split(",") if v):
        row = []
        for k in (t + round(s * fps) for s in (-1.0, -0.5, 0.0, 0.5, 1.0)):
            frame = video[min(max(k, 0), len(video) - 1)].copy()
            cv2.line(frame, (x0, y0), (x1, y1), (0, 0, 255), 1)
            crop = cv2.resize(frame[box[1]:box[3], box[0]:box[2]], None, fx=1.5, fy=1.5)
            cv2.putText(crop, str(k), (3, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 0), 1)
            row.append(crop)
        rows.append(np.hstack(row))
    if rows:
        cv2.imwrite(str(args.out / "crossings.png"), np.vstack(rows))


if __name__ == "__main__":
    main()
