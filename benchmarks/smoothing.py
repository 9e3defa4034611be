"""Output smoothing against its cost: lag against jitter. The shipped test clips (every 6th, at 30 fps) through
the four Human3.6M cameras of S9, as perfect 2D and with Gaussian pixel noise (a detector's jitter), lifted by
a shipped model with the track-level refinement (as `ray3d lift` runs), then each output smoothing applied
(`temporal.smooth`, the last step of `Lifter.lift`). Per method: MRPE and MPJPE (mm), jitter (the mean joint
acceleration, m/s^2, against the truth's own), and lag (the delay, ms, that best aligns the predicted root
velocity with the truth's).

    python benchmarks/smoothing.py [--model ray3d] [--noise 0 3]
"""

from __future__ import annotations

import argparse

import numpy as np

from ray3d import cameras, metrics, temporal
from ray3d.data.motion import load_shipped
from ray3d.data.virtual_cameras import centre_clip
from ray3d.jobs import load_lifter

FPS = 30.0


def acceleration(joints: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(joints, 2, axis=0), axis=-1).mean() * FPS ** 2)


def lag_ms(predicted_root: np.ndarray, true_root: np.ndarray, most: int = 6) -> float:
    """The shift (ms, positive: the prediction comes late) that best matches the two root velocities."""
    p, t = np.diff(predicted_root, axis=0), np.diff(true_root, axis=0)
    errors = {k: np.mean((p[k:] - t[:len(t) - k]) ** 2) if k >= 0 else np.mean((p[:k] - t[-k:]) ** 2)
              for k in range(-most, most + 1)}
    return 1e3 * min(errors, key=errors.get) / FPS


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default="ray3d")
    parser.add_argument("--noise", type=float, nargs="+", default=[0.0, 3.0], help="pixel noise sd")
    args = parser.parse_args()
    motion = load_shipped(None, "test")
    clips = [centre_clip(motion.clip(i).astype(float))[::2] for i in range(0, motion.num_clips, 6)]
    views = [cameras.h36m("S9", c) for c in ("54138969", "55011271", "58860488", "60457274")]
    lifter = load_lifter(args.model)
    rng = np.random.default_rng(0)
    methods = (None, "savgol", "one-euro")
    for noise in args.noise:
        scores = {m: {"mrpe": [], "mpjpe": [], "jitter": [], "lag": []} for m in methods}
        truth_jitter = []
        for camera in views:
            for clip in clips:
                if not camera.sees(clip):
                    continue
                pixels = camera.project(clip) + rng.normal(0.0, noise, (len(clip), 17, 2))
                raw = lifter.lift(pixels, camera, fps=FPS).joints
                truth_jitter.append(acceleration(clip))
                for method in methods:
                    joints = temporal.smooth(raw, method, FPS)
                    scores[method]["mrpe"].append(1e3 * metrics.mrpe(joints, clip))
                    scores[method]["mpjpe"].append(1e3 * metrics.mpjpe(joints, clip))
                    scores[method]["jitter"].append(acceleration(joints))
                    scores[method]["lag"].append(lag_ms(joints[:, 0], clip[:, 0]))
        print(f"{args.model}, {noise:g} px noise, {len(truth_jitter)} sequences at {FPS:g} fps "
              f"(truth's jitter {np.mean(truth_jitter):.2f} m/s^2):")
        for method, s in scores.items():
            print(f"  {method or 'none':9s} MRPE {np.mean(s['mrpe']):6.1f} mm  MPJPE {np.mean(s['mpjpe']):6.1f} mm  "
                  f"jitter {np.mean(s['jitter']):6.2f} m/s^2  lag {np.mean(s['lag']):5.1f} ms")


if __name__ == "__main__":
    main()
