"""A model's distance error on input like users': the detector emulation of ``ray3d bench level`` (real detectors'
joint offsets, statures 1.45-1.95 m, joints outside the picture unseen) through the level-test cameras (0.9-1.5 m
high, 2.5-6 m away) and the far-test cameras (3-12 m high, 15-40 m away), the network alone. Per bin of the
distance the network predicts: the rms of each track's median relative error (what a track shares: the
refinement's ``depth_bias_sd``) and the median spread of the frames' errors about their track's (``depth_sd``:
the near tracks' median, as the form a + b d cannot fall with the distance as the spread does),
written as the ``uncertainty`` a model document states.

    .venv/bin/python benchmarks/distance_errors.py CHECKPOINT OUT.json
"""

import json
import sys

import numpy as np

from ray3d.bench.level import run
from ray3d.data.motion import load_shipped
from ray3d.data.virtual_cameras import grid
from ray3d.jobs import load_lifter

BINS_M = (0.0, 4.0, 8.0, 16.0, 30.0, 60.0)
NEAR_M = 8.0


def main() -> None:
    checkpoint, out = sys.argv[1], sys.argv[2]
    lifter, motion = load_lifter(checkpoint), load_shipped(None, "test")
    rows = [r for cameras in ("level-test", "far-test") for r in run(lifter, motion, cameras=grid(cameras), seed=1)
            if "refused" not in r]
    distance = np.array([r["network_predicted_distance_m"] for r in rows])
    shared = np.array([r["network_distance_error"] for r in rows])
    spread = np.array([r["network_distance_error_frame_sd"] for r in rows])
    table = []
    for low, high in zip(BINS_M[:-1], BINS_M[1:]):
        inside = (distance >= low) & (distance < high)
        if inside.sum() >= 5:
            table.append({"from_m": low, "to_m": high, "pairs": int(inside.sum()),
                          "median_distance_m": float(np.median(distance[inside])),
                          "shared_rms": float(np.sqrt(np.mean(shared[inside] ** 2))),
                          "frame_sd": float(np.median(spread[inside]))})
    # The frames' spread falls with the distance here (4-5 % near, 1 % far), where the refinement's form a + b d
    # grows: a is the near tracks' median (where the refinement leans on the network most), b = 0.
    near = float(np.median(spread[distance < NEAR_M]))
    result = {"checkpoint": checkpoint, "pairs": len(rows), "bins": table,
              "uncertainty": {"depth_bias_sd": [[round(b["median_distance_m"], 1), round(b["shared_rms"], 4)]
                                                for b in table],
                              "depth_sd": [round(near, 4), 0.0]}}
    with open(out, "w") as handle:
        json.dump(result, handle, indent=1)
    for b in table:
        print(f"{b['from_m']:>4.0f}-{b['to_m']:<4.0f} m  {b['pairs']:>4} pairs  "
              f"shared rms {100 * b['shared_rms']:.1f} %  frame sd {100 * b['frame_sd']:.1f} %")
    print(json.dumps(result["uncertainty"]))


if __name__ == "__main__":
    main()
