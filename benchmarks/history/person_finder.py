"""How many of the people in view ray3d's video detector finds (issue 67, 2026-12-07: "Everyone in view"). Now
``ray3d bench people`` (``ray3d.bench.people``, the annotation shipped as ``src/ray3d/bench/data/vtest_people.json``);
this is the command the history's figures name, kept running.

    python benchmarks/history/person_finder.py --video ../shared/data/real-video/vtest.avi \\
        --camera ../shared/data/real-video/vtest_camera.json [--finders none movenet-384 ...] [--finder-every 2]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ray3d.bench.people import ANNOTATION, FINDER_NAMES, read_annotation, row_line, run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--video", required=True, type=Path)
    parser.add_argument("--camera", required=True)
    parser.add_argument("--annotation", default=str(ANNOTATION))
    parser.add_argument("--finders", nargs="+", default=["none", "movenet-384", "movenet-384-2x1"],
                        help=FINDER_NAMES)
    parser.add_argument("--finder-every", type=int, default=1, help="the finder on every n-th frame only")
    parser.add_argument("--out", help="write the rows as JSON here")
    args = parser.parse_args()
    annotated = read_annotation(args.annotation)
    rows = []
    for finder in args.finders:
        rows.append(run(args.video, args.camera, finder, annotated, args.finder_every))
        print(row_line(rows[-1]), flush=True)
    if args.out:
        Path(args.out).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
