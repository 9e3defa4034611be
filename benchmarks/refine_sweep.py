"""The track refinement's uncertainties, varied one at a time: GT 2D, the shipped model, every Nth frame.

    .venv/bin/python benchmarks/refine_sweep.py --cameras h36m --split test \\
        ankle_height_sd_m=0.07 robust_scale=1.0 depth_sd=0.03,0.003

Each VARIANT is a ``RefineConfig`` field and its value (a tuple field takes comma-separated numbers); the first
row is the configuration ``ray3d evaluate --refine`` uses with GT 2D (``keypoint_error`` 0), the second the
network alone. ``--exclude-clips PREFIX`` leaves out the clips whose id starts with it (e.g. ``cmu_03``, the
CMU subject who walks over stairs and uneven ground: the floor z = 0 is not under their feet). ``--per-subject``
adds, per mocap subject, the true lowest ankle's median height and MRPE without and with the default refinement.
"""

import argparse
import dataclasses

import numpy as np

from ray3d import evaluate as evaluation
from ray3d.data.virtual_cameras import grid
from ray3d.refine import RefineConfig
from ray3d.skeleton import H36M17

GT_2D = RefineConfig(keypoint_error=0.0)


def variant(text: str) -> RefineConfig:
    field, _, value = text.partition("=")
    default = getattr(GT_2D, field)  # an unknown field fails here, naming it
    parsed = tuple(float(v) for v in value.split(",")) if isinstance(default, tuple) else type(default)(value)
    return dataclasses.replace(GT_2D, **{field: parsed})


def share_of_distance(result: dict) -> float:
    """The median over cameras of MRPE / camera-person distance (clips centred on the origin, pelvis ~0.9 m)."""
    return float(np.median([c["mrpe_mm"] / 1e3 / np.hypot(c["horizontal_distance_m"], c["height_m"] - 0.9)
                            for c in result["per_camera"].values()]))


def per_subject_table(motion, plain: dict, refined: dict) -> None:
    ankles = [H36M17.index("l_ankle"), H36M17.index("r_ankle")]
    print("| subject | clips | lowest ankle, median (truth) | MRPE, network only | MRPE, refined |")
    print("|---|---|---|---|---|")
    for subject in np.unique(motion.clips["subject"]):
        clips = np.flatnonzero(motion.clips["subject"] == subject)
        ids = [k for k in motion.clips["clip_id"][clips].astype(str) if k in plain["per_clip"]]
        if not ids:
            continue
        lowest = np.median(np.concatenate([motion.clip(i)[:, ankles, 2].min(-1) for i in clips]))

        def mean_mrpe(result: dict) -> float:
            frames = np.array([result["per_clip"][k]["frames"] for k in ids])
            return float(np.average([result["per_clip"][k]["mrpe_mm"] for k in ids], weights=frames))

        print(f"| {subject} | {len(ids)} | {lowest:.3f} m | {mean_mrpe(plain):.0f} mm | {mean_mrpe(refined):.0f} mm |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("variants", nargs="*", help="FIELD=VALUE of RefineConfig")
    parser.add_argument("--checkpoint", default="ray3d")
    parser.add_argument("--cameras", default="h36m")
    parser.add_argument("--split", default="test", choices=["train", "validation", "test"])
    parser.add_argument("--frame-stride", type=int, default=16)
    parser.add_argument("--exclude-clips", default=None, metavar="PREFIX")
    parser.add_argument("--per-subject", action="store_true")
    args = parser.parse_args()
    motion, _ = evaluation.evaluation_motion(split=args.split)
    if args.exclude_clips:
        motion = motion.select(~np.char.startswith(motion.clips["clip_id"].astype(str), args.exclude_clips))
    cameras = grid(args.cameras)
    rows = [("refined (GT-2D defaults)", GT_2D), ("network only", False)]
    rows += [(text, variant(text)) for text in args.variants]
    print(f"{args.checkpoint}, {args.cameras} cameras, {args.split} performers ({motion.num_clips} clips"
          f"{', without ' + args.exclude_clips + '*' if args.exclude_clips else ''}), "
          f"every {args.frame_stride}th frame")
    print("| refinement | Abs-MPJPE | MRPE | MRPE / distance |")
    print("|---|---|---|---|")
    results = []
    for label, refine in rows:
        results.append(evaluation.evaluate(args.checkpoint, motion, cameras, frame_stride=args.frame_stride,
                                           refine=refine))
        print(f"| {label} | {results[-1]['abs_mpjpe_mm']:.1f} mm | {results[-1]['mrpe_mm']:.1f} mm | "
              f"{100 * share_of_distance(results[-1]):.2f} % |", flush=True)
    if args.per_subject:
        per_subject_table(motion, plain=results[1], refined=results[0])


if __name__ == "__main__":
    main()
