"""Several cameras live, against known truth: the scenes of `fusion_mocap.py` (the test performers' walks seen
by 2-4 virtual cameras around a room, 3 px noise, each camera losing the person for 0.6 s, its track broken in
two; two people crossing, 3 cameras) played frame by frame through what `ray3d live` runs for several cameras:
each camera's tracks lifted causally as they arrive (`LiftStream` without waiting, the network's own position sd),
then joined and fused by `ray3d.fusion.live.LiveFusion`.

Reports: world people per true person (1 = no identity switch: hand-overs and broken tracks joined), the live
fused pelvis and Abs-MPJPE error against the best single camera's live answer on the frames two or more cameras
see, and the crossing scenes' people and identity switches.

    .venv/bin/python benchmarks/live_fusion_mocap.py --clips 8
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from fusion_mocap import FPS, cameras, crossing_people, identity_switches, scene_arguments, seen, test_walks  # noqa: E402

from ray3d import Lifter  # noqa: E402
from ray3d.fusion.live import LiveFusion  # noqa: E402
from ray3d.geometry.uncertainty import PersonNow  # noqa: E402
from ray3d.refine import RefineConfig, network_position_sd  # noqa: E402


def live(lifter: Lifter, views: list, tracks: list[dict], frames: int) -> tuple[dict, list[dict]]:
    """Every frame, every camera's people lifted at once and fused: {world id: {frame: joints}} and, per
    camera, {frame: [joints of each track seen]}."""
    config = RefineConfig.for_model(lifter.document)
    streams = [{name: lifter.stream(c, "h36m17", fps=FPS, wait_for_future=False) for name in t}
               for c, t in zip(views, tracks)]
    numbers = [{name: k for k, name in enumerate(t)} for t in tracks]
    fusion = LiveFusion(views, 1.0 / FPS)
    fused: dict[int, dict[int, np.ndarray]] = {}
    single: list[dict[int, list]] = [{} for _ in views]
    for f in range(frames):
        for view, (camera, camera_tracks) in enumerate(zip(views, tracks)):
            people = []
            for name, (track_frames, pixels) in camera_tracks.items():
                if f in track_frames:
                    raw = streams[view][name].push(pixels[int(np.searchsorted(track_frames, f))])
                    sd = network_position_sd(raw[None], camera, config)[0]
                    people.append(PersonNow(numbers[view][name], raw, sd, None))
                    single[view].setdefault(f, []).append(raw)
                elif len(track_frames) and f == track_frames[-1] + int(FPS / 2):  # the tracker lets it go
                    fusion.finished(view, numbers[view][name])
            for now in fusion.update(view, f / FPS, people):
                fused.setdefault(now.track, {})[f] = now.joints
    return fused, single


def main() -> None:
    args = scene_arguments(__doc__)
    rng = np.random.default_rng(args.seed)
    lifter = Lifter.load()
    walks = test_walks(args.clips)
    per_person, pelvis, mpjpe = [], [], []
    for count in (2, 3, 4):
        views, _ = cameras(count)
        for walk in walks:
            tracks = [seen(c, walk[None], rng) for c in views]
            fused, single = live(lifter, views, tracks, len(walk))
            per_person.append(len(fused))
            several = [f for f in range(len(walk)) if sum(f in s for s in single) >= 2]
            if len(several) < FPS:
                continue
            track = max(fused.values(), key=len)
            frames = [f for f in several if f in track]
            fused_error = np.array([np.linalg.norm(track[f] - walk[f], axis=-1) for f in frames])
            singles = [np.array([np.linalg.norm(s[f][0] - walk[f], axis=-1) for f in frames if f in s]) for s in single]
            best = min((e for e in singles if len(e)), key=lambda e: e.mean())
            pelvis.append((fused_error[:, 0].mean(), best[:, 0].mean()))
            mpjpe.append((fused_error.mean(), best.mean()))
    crossing = []
    for people in crossing_people(walks):
        views, _ = cameras(3)
        fused, _ = live(lifter, views, [seen(c, people, rng) for c in views], people.shape[1])
        switches = sum(identity_switches(people, sorted(track), np.stack([track[f][0] for f in sorted(track)]))
                       for track in fused.values())
        crossing.append((len(fused), switches))
    pelvis, mpjpe = np.array(pelvis), np.array(mpjpe)
    print(f"{len(walks)} test walks x 2, 3, 4 cameras, live: world people per person "
          f"{np.bincount(per_person).tolist()} (index = people; 1 = no identity switch)")
    print(f"where two or more cameras see, live fused vs best single camera live: pelvis "
          f"{1000 * pelvis[:, 0].mean():.1f} vs {1000 * pelvis[:, 1].mean():.1f} mm, Abs-MPJPE "
          f"{1000 * mpjpe[:, 0].mean():.1f} vs {1000 * mpjpe[:, 1].mean():.1f} mm "
          f"({100 * (1 - mpjpe[:, 0].mean() / mpjpe[:, 1].mean()):.1f} % lower; {len(mpjpe)} scenes)")
    print(f"two people crossing, 3 cameras, live: (world people, identity switches) {crossing}")


if __name__ == "__main__":
    main()
