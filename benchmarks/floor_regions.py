"""People on stairs, with and without the stairs declared as floor regions: GT 2D, the shipped model, the test
performers, every Nth frame.

    .venv/bin/python benchmarks/floor_regions.py --cameras h36m --frame-stride 16

Each test clip (centred on the origin) is lifted onto a flight of ``--steps`` steps (rise 0.17 m, run 0.30 m)
rising along +x from x = -0.9 m to a landing: every frame is raised by the height of the step under its lowest
ankle (the planted foot's).
Rows: the network alone; the refinement on the plain floor z = 0 (the floor test decides where the floor holds);
the refinement with the stairs declared as one flat region per step and the landing (``ray3d.geometry.floor``);
and with the flight declared as one ramp through the middles of its treads.
"""

import argparse

import numpy as np

from ray3d import evaluate as evaluation
from ray3d.body import lowest_ankles
from ray3d.checkpoints import load_model
from ray3d.data.virtual_cameras import centre_clip, grid
from ray3d.geometry.floor import Floor, FloorRegion
from ray3d.models.inference import inference_network
from ray3d.refine import RefineConfig, joint_directions, refine_track
from ray3d.temporal import sequence_windows

RISE, RUN, START, WIDTH = 0.17, 0.30, -0.9, 20.0


def stairs(steps: int) -> tuple[Floor, Floor]:
    """The flight as flat steps plus a landing, and as one ramp (the plane through the treads' middles) plus the
    landing."""
    def box(x0, x1):
        return [[x0, -WIDTH], [x1, -WIDTH], [x1, WIDTH], [x0, WIDTH]]

    top = START + steps * RUN
    landing = FloorRegion("landing", box(top, top + WIDTH), steps * RISE)
    flat = [FloorRegion(f"step {k + 1}", box(START + k * RUN, START + (k + 1) * RUN), (k + 1) * RISE)
            for k in range(steps)]
    low, high = RISE / 2, (steps + 0.5) * RISE  # the plane through the middles of the treads
    ramp = FloorRegion.from_vertex_heights("flight", box(START, top), [low, high, high, low])
    return Floor((*flat, landing)), Floor((ramp, landing))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--checkpoint", default="ray3d")
    parser.add_argument("--cameras", default="h36m")
    parser.add_argument("--frame-stride", type=int, default=16)
    parser.add_argument("--steps", type=int, default=6)
    args = parser.parse_args()
    steps, ramp = stairs(args.steps)
    motion, _ = evaluation.evaluation_motion(split="test")
    model = inference_network(load_model(args.checkpoint)[0])
    window = model.config.window
    clips = []
    for i in range(motion.num_clips):
        clip = centre_clip(motion.clip(i).astype(np.float64))
        clip[..., 2] += steps.height(lowest_ankles(clip)[:, None, :2])  # the planted foot's step carries the body
        clips.append((clip, float(motion.clips["fps"][i]) / args.frame_stride))
    config = RefineConfig(keypoint_error=0.0)
    rows = {"network only": [], "refined, plain floor": [], "refined, steps declared": [],
            "refined, ramp declared": []}
    on_floor = []
    for camera in grid(args.cameras):
        for clip, fps in clips:
            if not camera.sees(clip):
                continue
            windows = sequence_windows(clip, window)[::args.frame_stride]
            predicted, pixels = evaluation.predict_windows(model, windows, camera, return_pixels=True)
            truth = windows[:, window.target]
            rays = joint_directions(camera, pixels, model.config.input_skeleton)
            results = {"network only": predicted}
            plain, found = refine_track(predicted, camera, fps, rays, config=config)
            results["refined, plain floor"] = plain
            on_floor.append(found.floor_cue)
            results["refined, steps declared"] = refine_track(predicted, camera, fps, rays, config=config,
                                                              floor=steps)[0]
            results["refined, ramp declared"] = refine_track(predicted, camera, fps, rays, config=config,
                                                             floor=ramp)[0]
            for name, joints in results.items():
                rows[name].append(np.linalg.norm(joints[:, 0] - truth[:, 0], axis=-1))
    print(f"{args.checkpoint}, {args.cameras} cameras, test performers on {args.steps} steps "
          f"(rise {RISE} m, run {RUN} m), every {args.frame_stride}th frame; "
          f"{len(on_floor)} (camera, clip) pairs, {sum(map(len, on_floor)):,} frames")
    print(f"the plain floor's term used in {100 * np.concatenate(on_floor).mean():.1f} % of frames")
    network = np.concatenate(rows["network only"]).mean()
    print("| lifting | MRPE | / network only |\n|---|---|---|")
    for name, errors in rows.items():
        mrpe = np.concatenate(errors).mean()
        print(f"| {name} | {1e3 * mrpe:.1f} mm | {mrpe / network:.2f} |")


if __name__ == "__main__":
    main()
