"""BVH export round trip on lifted tracks: the bundled demo clip lifted by each shipped model, exported as BVH
(as `ray3d lift --out x.bvh` writes it, and with ``rigid=True``: rotations only), read back by ray3d's own BVH
importer; prints per-joint errors (mm) and the spread of the lifted bone lengths (what a fixed-length skeleton
cannot reproduce).

    python benchmarks/bvh_round_trip.py [--models ray3d ray3d-real] [--out DIR]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from ray3d import cameras
from ray3d.data.bvh import read_bvh
from ray3d.demo import DEMO_CAMERA, demo_clip
from ray3d.io.bvh_export import Y_UP, bvh_text
from ray3d.io.world import World, write_world
from ray3d.jobs import load_lifter
from ray3d.skeleton import H36M17


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="+", default=["ray3d", "ray3d-real"])
    parser.add_argument("--out", type=Path, default=Path(tempfile.mkdtemp()))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    camera = cameras.h36m(*DEMO_CAMERA)
    pixels = camera.project(demo_clip())
    for model in args.models:
        lifted = load_lifter(model).lift(pixels, camera)
        world = World({"0": lifted}, camera, model)
        np.save(args.out / f"{model}.npy", lifted.joints)  # for an independent reader (bvh_bvhio_check.py)
        rigid = args.out / f"{model}-rigid.bvh"
        rigid.write_text(bvh_text(lifted.joints, H36M17, lifted.fps, rigid=True))
        bones = np.linalg.norm(lifted.joints[:, 1:] - lifted.joints[:, list(H36M17.parents[1:])], axis=-1)
        spread = 1e3 * np.abs(bones - np.median(bones, axis=0))
        print(f"{model}: {len(lifted.joints)} frames; lifted bone lengths differ from their median by "
              f"{np.median(spread):.1f} mm (median), {spread.max():.1f} mm (max)")
        for variant, path in (("default", write_world(args.out / f"{model}.bvh", world, overwrite=True)),
                              ("rigid", rigid)):
            nodes = read_bvh(path)
            back = nodes.positions()[:, [nodes.tree.names.index(n) for n in H36M17.joint_names]] @ Y_UP
            error = 1e3 * np.linalg.norm(back - lifted.joints, axis=-1)
            print(f"  {variant:8s} joint error mean {error.mean():.4f} mm, p99 {np.percentile(error, 99):.4f} mm, "
                  f"max {error.max():.4f} mm")


if __name__ == "__main__":
    main()
