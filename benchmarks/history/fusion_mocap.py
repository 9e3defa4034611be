"""Several cameras, one world, against known truth (issue 34): the test performers' walks seen by 2-4 virtual
cameras around a room, each camera's tracks lifted as `ray3d lift` lifts them, then fused. The scenes and the
figures now live in the library (``ray3d.bench.fusion``): ``ray3d bench fusion --clips 6 --out DIR`` gives them;
this is the command the history's figures name, kept running.

    python benchmarks/history/fusion_mocap.py --clips 6
"""

from __future__ import annotations

import argparse
import json

from ray3d.bench.fusion import offline, walking_clips
from ray3d.jobs import load_lifter


def main(measure=offline) -> None:
    """The scenes measured by ``measure`` (``ray3d.bench.fusion.offline`` or ``.live``), printed as JSON."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--clips", type=int, default=6)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    print(json.dumps(measure(load_lifter(), walking_clips(args.clips), args.seed), indent=1))


if __name__ == "__main__":
    main()
