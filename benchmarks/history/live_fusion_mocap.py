"""Several cameras live, against known truth (issue 34): the scenes of `fusion_mocap.py` played frame by frame
through what `ray3d live` runs for several cameras (causal lifting, `LiveFusion`). Now in the library
(``ray3d.bench.fusion.live``): ``ray3d bench fusion --live --clips 8 --out DIR`` gives the figures; this is the
command the history's figures name, kept running.

    python benchmarks/history/live_fusion_mocap.py --clips 8
"""

from fusion_mocap import main

from ray3d.bench.fusion import live

if __name__ == "__main__":
    main(live)
