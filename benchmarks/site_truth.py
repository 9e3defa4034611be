"""Site events against known truth: the test performers' walks seen by virtual cameras, lifted as `ray3d lift`
would (GT 2D pixels, the shipped model, refinement and savgol smoothing), against the same events read off the
mocap itself.

    .venv/bin/python benchmarks/site_truth.py --cameras h36m --clips 20

For every test clip whose pelvis travels at least 2 m, a 6 m line is put across its path at the path's middle
(perpendicular to its overall direction) and a 2 m square zone centred there. Per (camera, clip): whether the
lifted track crosses the line as often and in the same directions as the truth, the time differences, and the
dwell in the zone against the truth's. Then the same clips made child-sized (every bone x 0.7, re-grounded) for the
stature class; and each walk made a loiterer (stopping 20 s halfway, swaying 2 cm) for the dwell in a 2 m square
around the spot. Falls: every lifted pair checked for falls (there are none in these walks), and a scripted fall
(a test performer's first pose tipped over about the feet in 0.6 s, then lying still for 4 s; the mocap has no
fall) lifted from every camera that sees it; and falls made from the test performers' `lieDownFloor` clips
(the drop from the last standing frame to lying played 3x faster, then lying held 4 s, then the clip's getting up).
"""

import argparse

import numpy as np

from ray3d.data.samples import scale_bones
from ray3d.data.virtual_cameras import centre_clip, grid
from ray3d.evaluate import evaluation_motion
from ray3d.io.world import LiftResult
from ray3d.jobs import load_lifter
from ray3d.site.analytics import stature_class
from ray3d.site.events import SiteMonitor
from ray3d.site.falls import falls
from ray3d.site.places import CountingLine, Site, Zone, line_crossings

FPS = 30.0



def time_in_zone(joints: np.ndarray, zone: Zone) -> float:
    """Seconds a walker (world joints (T, 17, 3) at ``FPS``) spends in ``zone``, by the site monitor's rule."""
    monitor = SiteMonitor(Site((zone,)), FPS)
    for frame, pose in enumerate(joints):
        monitor.update(frame, {"walker": pose})
    return monitor.time_in_zones("walker")[zone.name]

def scene(clip: np.ndarray) -> tuple[CountingLine, Zone] | None:
    path = clip[:, 0, :2]
    travel = path[-1] - path[0]
    if np.linalg.norm(travel) < 2.0:
        return None
    middle = path[len(path) // 2]
    across = np.array([-travel[1], travel[0]]) / np.linalg.norm(travel)
    line = CountingLine("door", middle - 3 * across, middle + 3 * across)
    square = middle + np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float)
    return line, Zone("square", square)


def scripted_fall(pose: np.ndarray, seconds: float = 6.0) -> np.ndarray:
    """(T, 17, 3) a standing ``pose`` (17, 3) held for 1 s, tipped over about its feet by 88 degrees in 0.6 s,
    then lying still."""
    t = np.arange(int(seconds * FPS)) / FPS
    feet = np.array([pose[0, 0], pose[0, 1], 0.0])
    frames = []
    for angle in np.radians(np.clip((t - 1.0) / 0.6, 0, 1) * 88):
        rotation = np.array([[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]])
        frames.append((pose - feet) @ rotation.T + feet)
    return np.array(frames)


def loiterer(clip: np.ndarray, stay_s: float = 20.0) -> np.ndarray:
    """A walk that stops halfway for ``stay_s`` (its middle pose held, swaying 2 cm) and then walks on: the second
    half shifted so that the path is continuous."""
    half = len(clip) // 2
    hold = int(stay_s * FPS)
    sway = 0.02 * np.sin(np.arange(hold) / FPS * 2 * np.pi * 0.3)[:, None, None] * np.array([1.0, 0.0, 0.0])
    held = np.repeat(clip[half:half + 1], hold, axis=0) + sway
    return np.concatenate([clip[:half], held, clip[half:] + (held[-1, 0] - clip[half, 0]) * [1, 1, 0]])


def fast_lying_down(clip: np.ndarray, speed: float = 3.0, hold_s: float = 4.0) -> np.ndarray | None:
    """A fall made from a clip of lying down on the floor: the frames from the head's last standing height to its
    lowest played ``speed`` times faster (every ``speed``-th frame), then the lying pose held ``hold_s``, then the
    rest of the clip (getting up, where it has it). None if the head never drops 1 m."""
    from ray3d.body import HEAD

    head = clip[:, HEAD, 2]
    lowest = int(np.argmin(head))
    standing = np.flatnonzero(head[:lowest] > head[lowest] + 1.0)
    if not len(standing):
        return None
    start = int(standing[-1]) - int(FPS)  # a second before the last standing frame
    start = max(start, 0)
    drop = clip[start:lowest + 1][::int(speed)]
    return np.concatenate([clip[:start], drop, np.repeat(clip[lowest:lowest + 1], int(hold_s * FPS), axis=0),
                           clip[lowest:]])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cameras", default="h36m")
    parser.add_argument("--camera-stride", type=int, default=4)
    parser.add_argument("--clips", type=int, default=20)
    args = parser.parse_args()
    motion, _ = evaluation_motion(split="test")
    lifter = load_lifter()
    cameras = grid(args.cameras)[::args.camera_stride]
    same, crossings, time_errors, dwell_errors, classes, children = 0, 0, [], [], [], []
    loiter_errors = []
    false_falls = 0
    used = 0
    for i in range(motion.num_clips):
        if used >= args.clips:
            break
        step = int(round(float(motion.clips["fps"][i]) / FPS))
        clip = centre_clip(motion.clip(i).astype(np.float64))[::step]
        placed = scene(clip)
        if placed is None or len(clip) < 30:
            continue
        used += 1
        line, zone = placed
        times = np.arange(len(clip)) / FPS
        truth_crossings = line_crossings(times, clip[:, 0, :2], line)
        truth_dwell = time_in_zone(clip, zone)
        child = scale_bones(clip, np.full(clip.shape[:2], 0.7))
        for camera in cameras:
            if not camera.sees(clip):
                continue
            result: LiftResult = lifter.lift(camera.project(clip), camera, fps=FPS, smooth_3d="savgol")
            lifted = line_crossings(times, result.root[:, :2], line)
            crossings += 1
            if [c["direction"] for c in lifted] == [c["direction"] for c in truth_crossings]:
                same += 1
                time_errors += [abs(a["time_s"] - b["time_s"]) for a, b in zip(lifted, truth_crossings)]
            if truth_dwell > 0.5:
                dwell = time_in_zone(result.joints, zone)
                dwell_errors.append(abs(dwell - truth_dwell) / truth_dwell)
            classes.append(stature_class(result.refinement["stature_m"], result.refinement["stature_interval_m"]))
            false_falls += len(falls(times, result.joints))
            staying = loiterer(clip)
            stay_zone = Zone("spot", staying[len(clip) // 2, 0, :2] + np.array([[-1, -1], [1, -1], [1, 1], [-1, 1.0]]))
            if camera.sees(staying):
                truth_stay = time_in_zone(staying, stay_zone)
                lifted_stay = lifter.lift(camera.project(staying), camera, fps=FPS, smooth_3d="savgol").joints
                stay = time_in_zone(lifted_stay, stay_zone)
                loiter_errors.append(abs(stay - truth_stay) / truth_stay)
            if camera.sees(child):
                small = lifter.lift(camera.project(child), camera, fps=FPS, smooth_3d="savgol").refinement
                children.append(stature_class(small["stature_m"], small["stature_interval_m"]))
    made = []  # falls made from the test performers' lying down, found on the truth and through lifting
    for i in np.flatnonzero(np.char.find(motion.clips["clip_id"].astype(str), "lieDownFloor") >= 0):
        step = int(round(float(motion.clips["fps"][i]) / FPS))
        fallen = fast_lying_down(centre_clip(motion.clip(i).astype(np.float64))[::step])
        if fallen is None:
            continue
        made_times = np.arange(len(fallen)) / FPS
        truth_falls = len(falls(made_times, fallen))
        made.append(("truth", truth_falls))
        for camera in cameras:
            if camera.sees(fallen):
                lifted = lifter.lift(camera.project(fallen), camera, fps=FPS, smooth_3d="savgol").joints
                made.append(("lifted", len(falls(made_times, lifted))))
                made.append(("lifted as the truth", int(made[-1][1] == truth_falls)))
    every_clip_falls, every_clip_s = 0, 0.0  # every test clip (sitting, bending, jumping, lying down) lifted
    for i in range(motion.num_clips):
        step = int(round(float(motion.clips["fps"][i]) / FPS))
        clip = centre_clip(motion.clip(i).astype(np.float64))[::step]
        for camera in (camera for camera in cameras if len(clip) >= 30 and camera.sees(clip)):
            lifted = lifter.lift(camera.project(clip), camera, fps=FPS, smooth_3d="savgol").joints
            every_clip_falls += len(falls(np.arange(len(clip)) / FPS, lifted))
            every_clip_s += len(clip) / FPS
    fall = scripted_fall(centre_clip(motion.clip(0).astype(np.float64))[0])
    fall_times = np.arange(len(fall)) / FPS
    found_falls = [len(falls(fall_times, lifter.lift(camera.project(fall), camera, fps=FPS, smooth_3d="savgol").joints))
                   for camera in cameras if camera.sees(fall)]
    time_errors, dwell_errors = np.array(time_errors), np.array(dwell_errors)
    print(f"{used} walking clips x {len(cameras)} {args.cameras} cameras: {crossings} (camera, clip) pairs")
    print(f"line crossings as the truth's (count and directions): {same} of {crossings}; time error median "
          f"{np.median(time_errors):.3f} s, max {time_errors.max():.3f} s, within 0.2 s "
          f"{100 * np.mean(time_errors <= 0.2):.1f} % of {len(time_errors)}")
    print(f"zone dwell: error median {100 * np.median(dwell_errors):.1f} %, within 5 % in "
          f"{100 * np.mean(dwell_errors <= 0.05):.1f} % of {len(dwell_errors)} pairs")
    agree = [n for k, n in made if k == "lifted as the truth"]
    print(f"falls made from lying down, lifted: as many as on the truth in {sum(agree)} of {len(agree)} pairs")
    for kind in ("truth", "lifted"):
        counts = [n for k, n in made if k == kind]
        print(f"falls made from the test performers' lying down (3x faster, then lying 4 s), {kind}: found once in "
              f"{counts.count(1)} of {len(counts)}, missed in {counts.count(0)}")
    loiter_errors = np.array(loiter_errors)
    print(f"loiterers (each walk stopping 20 s halfway, a 2 m square around the spot): dwell error median "
          f"{100 * np.median(loiter_errors):.1f} %, largest {100 * loiter_errors.max():.1f} %, within 5 % in "
          f"{100 * np.mean(loiter_errors <= 0.05):.1f} % of {len(loiter_errors)} pairs")
    print(f"falls in every test clip lifted from every camera that sees it whole: {every_clip_falls} in "
          f"{every_clip_s / 60:.1f} minutes of lifted motion")
    print(f"falls in the lifted walks: {false_falls}; the scripted fall lifted from {len(found_falls)} cameras: "
          f"found once in {found_falls.count(1)}, missed in {found_falls.count(0)}, more than once in "
          f"{sum(n > 1 for n in found_falls)}")
    print("stature classes, adults: " + ", ".join(f"{k} {classes.count(k)}" for k in ("adult", "unsure", "child"))
          + "; child-sized (x0.7): " + ", ".join(f"{k} {children.count(k)}" for k in ("adult", "unsure", "child")))


if __name__ == "__main__":
    main()
