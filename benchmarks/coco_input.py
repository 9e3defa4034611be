"""COCO-17 input against H36M-17 input: the same test clips (every 6th, at 30 fps) through the four Human3.6M
cameras of S9, perfect 2D. The mocap has no face points: the nose is put at the H36M neck/nose joint and the
eyes and ears between it and the head joint, offset sideways in the body frame (3 and 7 cm). Prints MRPE per
input and their ratio, for ray3d and ray3d-real, without and with the refinement.

    .venv/bin/python benchmarks/coco_input.py
"""
import numpy as np
from ray3d import cameras, metrics
from ray3d.data.motion import load_shipped
from ray3d.data.samples import body_frames
from ray3d.data.virtual_cameras import centre_clip
from ray3d.lift import Lifter
from ray3d.skeleton import COCO17, H36M17
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
for name in ("ray3d", "ray3d-real"):
    lifter = Lifter.load(name)
    for refine in (False, True):
        e = {"h36m17": [], "coco17": []}
        for cam in cams:
            for clip in clips:
                if not cam.sees(clip): continue
                for layout, world in (("h36m17", clip), ("coco17", coco_world(clip))):
                    r = lifter.lift(cam.project(world), cam, fps=30, layout=layout, refine=refine)
                    e[layout].append(metrics.mrpe(r.joints, clip))
        h, c = 1e3 * np.mean(e["h36m17"]), 1e3 * np.mean(e["coco17"])
        print(f"{name} refine={refine}: MRPE H36M-17 input {h:.0f} mm, COCO-17 input {c:.0f} mm, ratio x{c / h:.2f} ({len(e['coco17'])} pairs)")
