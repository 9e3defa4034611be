"""Restarts lose nothing and count nothing twice (issue 60): ``ray3d live --unpaced`` once uninterrupted (twice),
and once killed with SIGKILL at ``--kills`` random moments and started again each time on the same store. Now
``ray3d bench live VIDEO --mode restarts`` (``ray3d.bench.restarts``, where what each figure means is said);
this is the command the history's figures name, kept running, and ``--analyse`` reads an earlier run's stores again.

    python benchmarks/history/live_restarts.py ../shared/data/real-video/vtest.avi \\
        --camera ../shared/data/real-video/vtest_camera.json --site benchmarks/vtest_site.json --out DIR
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ray3d.bench.restarts import restarts, restarts_figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("video", type=Path)
    parser.add_argument("--camera", required=True)
    parser.add_argument("--site", required=True, type=Path)
    parser.add_argument("--out", required=True, type=Path)
    parser.add_argument("--kills", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--analyse", action="store_true", help="only analyse the outputs of an earlier run in --out")
    args = parser.parse_args()
    if args.analyse:
        result = restarts_figures(args.out / "uninterrupted", args.out / "uninterrupted-again", args.out / "killed")
    else:
        result = restarts(args.video, args.camera, args.out, args.site, args.kills, args.seed)
    for key, value in result.items():
        print(f"{key}: {json.dumps(value)}")


if __name__ == "__main__":
    main()
