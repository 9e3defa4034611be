"""Several cameras live, against known truth (issue 34): the scenes of `fusion_mocap.py` played frame by frame
through what `ray3d live` runs for several cameras (causal lifting, `LiveFusion`). Now in the library
(``ray3d.bench.fusion.live``): ``ray3d bench fusion --live --clips 8 --out DIR`` gives the figures; this is the
command the history's figures name, kept running.

    python benchmarks/history/live_fusion_mocap.py --clips 8
"""

from __future__ import annotations

import argparse
import json

from ray3d.bench.fusion import live, walking_clips
from ray3d.jobs import load_lifter


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--clips", type=int, default=6)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    print(json.dumps(live(load_lifter(), walking_clips(args.clips), args.seed), indent=1))


if __name__ == "__main__":
    main()
