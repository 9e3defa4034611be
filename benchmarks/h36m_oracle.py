"""Where the refined h36m error lies: Abs-MPJPE with the root, or one scale per track, taken from the truth.

Usage: python benchmarks/h36m_oracle.py [MODEL] [CAMERA_SET]; every 16th frame, test performers, GT 2D."""
import sys

import numpy as np

import ray3d.evaluate as ev
from ray3d import metrics
from ray3d.checkpoints import load_model
from ray3d.data.virtual_cameras import centre_clip, grid
from ray3d.models.inference import inference_network
from ray3d.refine import joint_directions, refine_track
from ray3d.temporal import sequence_windows


def main() -> None:
    stride = 16
    name = sys.argv[1] if len(sys.argv) > 1 else "ray3d"
    sets = sys.argv[2] if len(sys.argv) > 2 else "h36m"
    motion, _ = ev.evaluation_motion()
    model = inference_network(load_model(name)[0])
    window = model.config.window
    clips = [centre_clip(motion.clip(i).astype(np.float64)) for i in range(motion.num_clips)]
    windows = [sequence_windows(c, window)[::stride] for c in clips]
    res = {k: [] for k in ["base", "rays", "oracle_scale", "oracle_root", "oracle_root_scale"]}
    ratios = []
    for camera in grid(sets):
        seen = [i for i, c in enumerate(clips) if camera.sees(c)]
        if not seen:
            continue
        stacked = np.concatenate([windows[i] for i in seen])
        pred, pix = ev.predict_windows(model, stacked, camera, return_pixels=True)
        truth_all = stacked[:, window.target]
        b = np.cumsum([0] + [len(windows[i]) for i in seen])
        for k, i in enumerate(seen):
            tr = slice(b[k], b[k+1])
            truth = truth_all[tr]
            rays = joint_directions(camera, pix[tr], model.config.input_skeleton)
            ref, info = refine_track(pred[tr], camera, float(motion.clips["fps"][i]) / stride, rays)
            r = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
            C = camera.center
            on = C + np.einsum("tjk,tjk->tj", ref - C, r)[..., None] * r
            res["base"].append(metrics.abs_mpjpe(ref, truth, reduction="none"))
            res["rays"].append(metrics.abs_mpjpe(on, truth, reduction="none"))
            # oracle single scale about the camera centre (fit root distance)
            d_p = np.linalg.norm(on[:, 0] - C, axis=-1)
            d_t = np.linalg.norm(truth[:, 0] - C, axis=-1)
            s = np.median(d_t / d_p)
            ratios.append(s)
            res["oracle_scale"].append(metrics.abs_mpjpe(C + s * (on - C), truth, reduction="none"))
            # oracle root: shift the whole pose so root matches truth
            res["oracle_root"].append(metrics.abs_mpjpe(on - on[:, :1] + truth[:, :1], truth, reduction="none"))
            # oracle per-frame scale along rays (root distance exact per frame)
            st = d_t / d_p
            res["oracle_root_scale"].append(metrics.abs_mpjpe(C + st[:, None, None] * (on - C), truth,
                                                              reduction="none"))
    print(name, sets, {k: round(1e3 * np.concatenate(v).mean(), 1) for k, v in res.items()})
    ratios = np.array(ratios)
    print("track scale ratio truth/pred: median %.4f, sd %.4f, p10 %.4f p90 %.4f"
          % (np.median(ratios), ratios.std(), *np.percentile(ratios, [10, 90])))


if __name__ == "__main__":
    main()
