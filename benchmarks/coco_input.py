"""COCO-17 input against H36M-17 input: the same test clips (every 6th, at 30 fps) through the four Human3.6M
cameras of S9, perfect 2D. The mocap has no face points: the nose is put at the H36M neck/nose joint and the
eyes and ears between it and the head joint, offset sideways in the body frame (3 and 7 cm). A third input is
COCO-17 as a detector measures it: each joint's definition moved by a random offset in the body frame (3 cm
standard deviation per axis, fixed per clip: another detector's idea of where a hip is) and 3 px of Gaussian
jitter per frame. Prints MRPE per input and the ratios to H36M-17, for ray3d and ray3d-real, without and with
the refinement (``--smooth-3d savgol`` smooths every lifted sequence, as ``ray3d video`` does).

    .venv/bin/python benchmarks/coco_input.py [--models ray3d ray3d-real] [--smooth-3d savgol]
"""
import argparse

import numpy as np
from ray3d import cameras, metrics
from ray3d.data.motion import load_shipped
from ray3d.data.samples import body_frames
from ray3d.data.virtual_cameras import centre_clip
from ray3d.lift import Lifter
from ray3d.skeleton import COCO17, H36M17
parser = argparse.ArgumentParser()
parser.add_argument("--models", nargs="+", default=["ray3d", "ray3d-real"])
parser.add_argument("--smooth-3d", choices=["savgol", "one-euro"])
args = parser.parse_args()
I = H36M17.index
m = load_shipped(None, "test")
clips = [centre_clip(m.clip(i).astype(float))[::2] for i in range(0, m.num_clips, 6)]
cams = [cameras.h36m("S9", c) for c in ("54138969", "55011271", "58860488", "60457274")]
def coco_world(clip):
    frames = body_frames(clip)  # (T, 3, 3): x to the left hip, y forward, z up
    nose, head = clip[:, I("neck_nose")], clip[:, I("head")]
    side = frames[..., 0]
    out = np.zeros((len(clip), 17, 3))
    for j, n in enumerate(COCO17.joint_names):
        if n in H36M17.joint_names: out[:, j] = clip[:, I(n)]
    mid = 0.6 * nose + 0.4 * head
    out[:, 0] = nose
    out[:, 1], out[:, 2] = mid + 0.03 * side, mid - 0.03 * side
    out[:, 3], out[:, 4] = mid + 0.07 * side - 0.03 * frames[..., 1], mid - 0.07 * side - 0.03 * frames[..., 1]
    return out
rng = np.random.default_rng(0)
for name in args.models:
    lifter = Lifter.load(name)
    for refine in (False, True):
        e = {"h36m17": [], "coco17": [], "coco17 noisy": []}
        for cam in cams:
            for clip in clips:
                if not cam.sees(clip): continue
                coco = coco_world(clip)
                axes = body_frames(clip)  # (T, 3, 3) columns: left, forward, up
                offsets = rng.normal(0.0, 0.03, (17, 3))  # per joint, in the body frame, fixed over the clip
                moved = coco + np.einsum("tij,kj->tki", axes, offsets)
                noisy = cam.project(moved) + rng.normal(0.0, 3.0, (len(clip), 17, 2))
                for key, layout, pixels in (("h36m17", "h36m17", cam.project(clip)), ("coco17", "coco17", cam.project(coco)),
                                            ("coco17 noisy", "coco17", noisy)):
                    r = lifter.lift(pixels, cam, fps=30, layout=layout, refine=refine, smooth_3d=args.smooth_3d)
                    e[key].append(metrics.mrpe(r.joints, clip))
        h, c, n = (1e3 * np.mean(e[k]) for k in ("h36m17", "coco17", "coco17 noisy"))
        print(f"{name} refine={refine}: MRPE H36M-17 input {h:.0f} mm, COCO-17 input {c:.0f} mm (x{c / h:.2f}), "
              f"COCO-17 with moved joints and 3 px noise {n:.0f} mm (x{n / h:.2f}) ({len(e['coco17'])} pairs)")
