"""COCO-17 input against H36M-17 input: the same test clips (every 6th, at 30 fps) through the four Human3.6M
cameras of S9, perfect 2D. The mocap has no face points: they are placed from the upper neck as training does
(``ray3d.data.samples.detector_points``). A third input is COCO-17 as a detector measures it: each joint's
definition moved by a random offset in the body frame (3 cm standard deviation per axis, fixed per clip:
another detector's idea of where a hip is) and 3 px of Gaussian jitter per frame. Prints MRPE per input and the
ratios to H36M-17 input of the same model (of ``--h36m-model`` for a model that reads only detector joints),
without and with the refinement (``--smooth-3d savgol`` smooths every lifted sequence, as ``ray3d video`` does).

    .venv/bin/python benchmarks/coco_input.py [--models ray3d ray3d-real ray3d-detector] [--smooth-3d savgol]
"""
import argparse

import numpy as np

from ray3d import cameras, metrics
from ray3d.data.detector_emulation import body_frames, detector_points, offset_joints
from ray3d.data.motion import load_shipped
from ray3d.data.virtual_cameras import centre_clip
from ray3d.jobs import load_lifter
from ray3d.skeleton import COCO17


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--models", nargs="+", default=["ray3d", "ray3d-real", "ray3d-detector"])
    parser.add_argument("--h36m-model", default="ray3d", help="the H36M-17 reference of detector-only models")
    parser.add_argument("--smooth-3d", choices=["savgol", "one-euro"])
    args = parser.parse_args()
    m = load_shipped(None, "test")
    clips = [centre_clip(m.clip(i).astype(float))[::2] for i in range(0, m.num_clips, 6)]
    cams = [cameras.h36m("S9", c) for c in ("54138969", "55011271", "58860488", "60457274")]
    rng = np.random.default_rng(0)
    for name in args.models:
        lifter = load_lifter(name)
        reference = lifter if lifter.model.config.layout == "h36m17" else load_lifter(args.h36m_model)
        for refine in (False, True):
            e = {"h36m17": [], "coco17": [], "coco17 noisy": []}
            for cam in cams:
                for clip in clips:
                    if not cam.sees(clip):
                        continue
                    coco = detector_points(clip, COCO17)
                    offsets = rng.normal(0.0, 0.03, (1, 17, 3))  # per joint, in the body frame, fixed over the clip
                    moved = offset_joints(coco[None], body_frames(clip)[None], offsets, COCO17)[0]
                    noisy = cam.project(moved) + rng.normal(0.0, 3.0, (len(clip), 17, 2))
                    for key, model, layout, pixels in (("h36m17", reference, "h36m17", cam.project(clip)),
                                                       ("coco17", lifter, "coco17", cam.project(coco)),
                                                       ("coco17 noisy", lifter, "coco17", noisy)):
                        r = model.lift(pixels, cam, fps=30, layout=layout, refine=refine, smooth_3d=args.smooth_3d)
                        e[key].append(metrics.mrpe(r.joints, clip))
            h, c, n = (1e3 * np.mean(e[k]) for k in ("h36m17", "coco17", "coco17 noisy"))
            print(f"{name} refine={refine}: MRPE H36M-17 input ({reference.name}) {h:.0f} mm, COCO-17 input {c:.0f} mm "
                  f"(x{c / h:.2f}), COCO-17 with moved joints and 3 px noise {n:.0f} mm (x{n / h:.2f}) "
                  f"({len(e['coco17'])} pairs)")


if __name__ == "__main__":
    main()
