"""Our BVH export read by an independent reader, bvhio (PyPI, not a ray3d dependency): the joints it computes
against the lifted joints written beside the file by `benchmarks/bvh_round_trip.py --out DIR`.

    python -m venv /tmp/bvhcheck && /tmp/bvhcheck/bin/pip install bvhio numpy
    /tmp/bvhcheck/bin/python benchmarks/bvh_bvhio_check.py DIR/ray3d.bvh DIR/ray3d.npy
"""

import sys

import bvhio
import numpy as np

# The H36M-17 joint names (ray3d.skeleton.H36M17), spelled out: this runs without ray3d installed.
NAMES = ("pelvis", "r_hip", "r_knee", "r_ankle", "l_hip", "l_knee", "l_ankle", "spine", "thorax", "neck_nose", "head",
         "l_shoulder", "l_elbow", "l_wrist", "r_shoulder", "r_elbow", "r_wrist")
BVH_TO_WORLD = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # y up -> z up (row vectors)


def main() -> None:
    root = bvhio.readAsHierarchy(sys.argv[1])
    lifted = np.load(sys.argv[2])
    worst = 0.0
    for frame in range(len(lifted)):
        root.loadPose(frame)
        joints = {joint.Name: joint for joint, _, _ in root.layout()}
        positions = np.array([list(joints[name].PositionWorld) for name in NAMES]) @ BVH_TO_WORLD
        worst = max(worst, float(np.abs(positions - lifted[frame]).max()))
    print(f"{sys.argv[1]}: {len(lifted)} frames, largest joint coordinate difference {1e3 * worst:.4f} mm")


if __name__ == "__main__":
    main()
