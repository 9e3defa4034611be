"""One person through ``Lifter.lift`` with its defaults from a calibration that is right (issue 66): the shipped
``ray3d`` on exact 2D of the mocap's test performers, seen by a camera 3 m high looking 20 degrees down at them
8 m away, the floor decided from the person against the same lift given the floor (``floor_z=0``).

    python benchmarks/one_person_floor.py [--clips N] [--seconds S]

Prints, per clip and in median, Abs-MPJPE (mm) both ways and the decision taken; a right calibration's floor
should be kept, the figure within 10 % of the one with the floor given."""

from __future__ import annotations

import argparse

import numpy as np

from ray3d import Camera, metrics
from ray3d.data import motion as motion_data
from ray3d.data.virtual_cameras import centre_clip
from ray3d.jobs import load_lifter


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clips", type=int, default=12)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    motion = motion_data.load_shipped(None, "test")
    lifter = load_lifter()
    camera = Camera.from_height_pitch(3.0, 20.0, (1920, 1080), hfov_deg=60.0, name="3m-20deg")
    ahead = camera.pixels_to_world_directions(np.array([[960.0, 540.0]]))[0]
    ahead = ahead[:2] / np.linalg.norm(ahead[:2])
    rng = np.random.default_rng(args.seed)
    rows = []
    for index in rng.choice(motion.num_clips, size=min(args.clips, motion.num_clips), replace=False):
        clip = centre_clip(motion.clip(int(index)).astype(np.float64))[:int(args.seconds * 60)]
        clip = clip + [*(camera.center[:2] + 8.0 * ahead), 0.0]
        pixels = camera.project(clip)
        decided = lifter.lift(pixels, camera, fps=60.0)
        given = lifter.lift(pixels, camera, fps=60.0, floor_z=0.0)
        plane = decided.refinement["ankle_plane"]
        rows.append((str(motion.clips["clip_id"][index]), 1e3 * metrics.abs_mpjpe(decided.joints, clip),
                     1e3 * metrics.abs_mpjpe(given.joints, clip), plane["decision"], plane["chance_off"]))
        print(f"{rows[-1][0]}: decided {rows[-1][1]:.1f} mm, floor given {rows[-1][2]:.1f} mm "
              f"({plane['decision']}, chance off {plane['chance_off']:.2f})", flush=True)
    decided_mm, given_mm = np.median([r[1] for r in rows]), np.median([r[2] for r in rows])
    print(f"median Abs-MPJPE over {len(rows)} clips: decided {decided_mm:.1f} mm, floor given {given_mm:.1f} mm "
          f"({decided_mm / given_mm:.3f}x); kept in {sum(r[3] == 'kept' for r in rows)} of {len(rows)}")


if __name__ == "__main__":
    main()
