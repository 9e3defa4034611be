"""Several cameras, one world, against known truth (``ray3d bench fusion``): the test performers' walks seen by 2-4
virtual cameras around a room (2-4 m high, 4-9 m from its centre), detector-like 2D noise (3 px per joint and
frame), each camera missing the person for 0.6 s somewhere (its track then breaks in two, as a tracker's would).

- ``offline``: each camera's tracks lifted as ``ray3d lift`` lifts them (refined, savgol), then fused as a job
  fuses them (``jobs.fuse_and_write``): world tracks per person (1 = no identity switch, hand-overs and broken
  tracks joined), fused Abs-MPJPE against the best single camera on the frames two or more cameras see, time
  offsets found (a camera's frames shifted by a known amount), two people crossing (tracks and switches), a camera
  placed 0.5 m off (which camera the agreement check names), and what fusing costs beside lifting;
- ``live``: the same scenes played frame by frame through what ``ray3d live`` runs for several cameras (each
  camera's tracks lifted causally as they arrive, ``LiftStream`` without waiting, joined and fused by
  ``fusion.live.LiveFusion``): world people per person, the live fused pelvis and Abs-MPJPE error against the best
  single camera's live answer, and the crossing scenes."""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from ray3d.data import motion as motion_data
from ray3d.data.virtual_cameras import centre_clip, mounted_camera
from ray3d.fusion import find_time_offset
from ray3d.fusion.live import LiveFusion
from ray3d.geometry.uncertainty import PersonNow
from ray3d.io.world import World
from ray3d.jobs import fuse_and_write
from ray3d.refine import RefineConfig, network_position_sd

FPS = 30.0
ROOM = [(0.0, 2.5, 5.0), (100.0, 3.5, 7.0), (190.0, 2.0, 4.0), (280.0, 4.0, 9.0)]  # yaw, height, distance
CAMERAS = (2, 3, 4)  # each walk seen by this many of the room's cameras in turn
NOISE_PX = 3.0
MISSED_S = 0.6  # longer than a tracker bridges: the track broken in two around it
SWITCH_HELD_S = 0.5  # a track following another person for this long is an identity switch


def room_cameras(count: int, moved: int | None = None) -> tuple[list, list]:
    """The first ``count`` cameras of the room, and the same as their files say: with ``moved``, that camera's file
    puts it 0.5 m from where it is."""
    made = [mounted_camera(yaw, height, distance, None, f"cam{k}")
            for k, (yaw, height, distance) in enumerate(ROOM[:count])]
    if moved is None:
        return made, made
    told = list(made)
    centre = made[moved].center + [0.5, 0.0, 0.0]
    told[moved] = dataclasses.replace(made[moved], t=-made[moved].R @ centre)
    return made, told


def seen(camera, people: np.ndarray, rng: np.random.Generator) -> dict:
    """{track: (frames, pixels)} of each person as one camera's tracker gives them: ``NOISE_PX`` noise, ``MISSED_S``
    missed somewhere (the track broken in two around it), frames out of the picture left out."""
    tracks = {}
    for p, clip in enumerate(people):
        pixels = camera.project(clip) + rng.normal(0, NOISE_PX, (len(clip), 17, 2))
        inside = np.all((pixels >= 0) & (pixels < camera.image_size), axis=(1, 2))
        frames = np.flatnonzero(inside)
        if len(frames) < 1.2 * FPS:
            continue
        start = rng.integers(frames[0] + int(FPS / 3), max(frames[0] + int(FPS / 3) + 1, frames[-1] - int(FPS)))
        for part, keep in enumerate((frames < start, frames >= start + int(MISSED_S * FPS))):
            if keep.sum() >= FPS / 3:
                tracks[f"{p}.{part}"] = (frames[keep], pixels[frames[keep]])
    return tracks


def walking_clips(count: int, data_dir=None) -> list[np.ndarray]:
    """The first ``count`` test clips at ``FPS`` of 2.5 s or more that travel 2 m or more, centred on the room."""
    motion = motion_data.load_shipped(data_dir, "test")
    walks = []
    for i in range(motion.num_clips):
        step = int(round(float(motion.clips["fps"][i]) / FPS))
        clip = centre_clip(motion.clip(i).astype(np.float64))[::step]
        if len(clip) >= 2.5 * FPS and np.linalg.norm(clip[-1, 0, :2] - clip[0, 0, :2]) >= 2.0:
            walks.append(clip)
        if len(walks) >= count:
            break
    return walks


def crossing_people(walks: list[np.ndarray]):
    """Scenes of two people, (2, T, 17, 3) each: a walk, and the next walk turned a quarter to cross it."""
    for a, b in zip(walks[:3], walks[1:4]):
        turned = b.copy()
        turned[..., :2] = turned[..., :2] @ np.array([[0.0, -1.0], [1.0, 0.0]])
        n = min(len(a), len(turned))
        yield np.stack([a[:n], turned[:n]])


def identity_switches(people: np.ndarray, frames, roots: np.ndarray) -> int:
    """How often a track (its roots (N, 3) at ``frames``) goes from following one of the ``people`` to the other
    for ``SWITCH_HELD_S`` or more (a frame or two where their paths cross, nearest either way, is none)."""
    nearest = np.array([np.argmin(np.linalg.norm(people[:, f, 0, :2] - root[:2], axis=-1))
                        for f, root in zip(frames, roots) if f < people.shape[1]])
    runs = np.split(nearest, np.flatnonzero(np.diff(nearest)) + 1)
    held = [run[0] for run in runs if len(run) >= SWITCH_HELD_S * FPS]
    return int(np.sum(np.diff(held) != 0))


def lifted(lifter, camera, tracks: dict, offset_frames: int = 0) -> World | None:
    """One camera's tracks lifted as ``ray3d lift`` lifts them (refined, savgol), its frames shifted by
    ``offset_frames``; None where it saw nobody."""
    if not tracks:
        return None
    shifted = {t: (frames + offset_frames, pixels) for t, (frames, pixels) in tracks.items()}
    return World(lifter.lift_tracks(shifted, camera, "h36m17", FPS, smooth_3d="savgol"), camera, lifter.name)


def _errors(world_track, truth: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """Abs-MPJPE (m) of a world track against the truth, per frame of ``frames`` it has."""
    shared, rows, _ = np.intersect1d(world_track.frames, frames, return_indices=True)
    return np.linalg.norm(world_track.joints[rows] - truth[shared], axis=-1).mean(axis=-1)


def _mean_mm(values) -> float | None:
    return round(1000 * float(np.mean(values)), 1) if len(values) else None


def _several_cameras(lifter, walks: list[np.ndarray], rng: np.random.Generator, cameras: tuple[int, ...]) -> dict:
    """Each walk seen by each of ``cameras`` cameras, lifted per camera and fused."""
    per_person, fused_error, best_error, seconds = [], [], [], {"lifting": 0.0, "fusing": 0.0}
    for count in cameras:
        views, _ = room_cameras(count)
        for walk in walks:
            started = time.perf_counter()
            worlds = [w for w in (lifted(lifter, c, seen(c, walk[None], rng)) for c in views) if w is not None]
            if len(worlds) < 2:
                continue
            lifted_at = time.perf_counter()
            fusion = fuse_and_write(worlds)
            if count == max(cameras):
                seconds["lifting"] += lifted_at - started
                seconds["fusing"] += time.perf_counter() - lifted_at
            per_person.append(len(fusion.world.tracks))
            track = max(fusion.world.tracks.values(), key=lambda r: len(r.frames))
            several = track.frames[track.seen_by.sum(axis=1) >= 2]
            if len(several) < FPS:
                continue
            fused_error.append(_errors(track, walk, several).mean())
            best_error.append(min(np.mean(np.concatenate([_errors(r, walk, several) for r in w.tracks.values()]))
                                  for w in worlds))
    fused_error, best_error = np.array(fused_error), np.array(best_error)
    return {"world tracks per person (index: tracks)": np.bincount(per_person).tolist(),
            "fused abs_mpjpe mm": _mean_mm(fused_error), "best single camera abs_mpjpe mm": _mean_mm(best_error),
            "scenes": len(fused_error),
            "fused lower in (share of scenes)": round(float(np.mean(fused_error < best_error)), 2)
            if len(fused_error) else None,
            f"fusing {max(cameras)} cameras costs (x the single-camera runs)":
                round(sum(seconds.values()) / seconds["lifting"], 2) if seconds["lifting"] else None}


def offline(lifter, walks: list[np.ndarray], seed: int = 0, cameras: tuple[int, ...] = CAMERAS) -> dict:
    """The offline figures (see the module's text) of ``walks`` lifted by ``lifter``, each seen by each of
    ``cameras`` cameras."""
    result = _several_cameras(lifter, walks, np.random.default_rng(seed), cameras)
    rng = np.random.default_rng(seed + 1)  # each part its own draws: reproducible alone
    offsets = []
    for walk in walks:  # a known shift of the second camera's frames
        views, _ = room_cameras(2)
        tracks = [seen(c, walk[None], rng) for c in views]
        shift = int(rng.integers(-20, 21))
        first, second = lifted(lifter, views[0], tracks[0]), lifted(lifter, views[1], tracks[1], shift)
        if first is not None and second is not None:
            found, sd = find_time_offset(first, second)
            offsets.append([shift, round(found * FPS, 2), round(sd * FPS, 2)])
    rng = np.random.default_rng(seed + 2)
    crossing = []
    for people in crossing_people(walks):
        views, _ = room_cameras(3)
        worlds = [lifted(lifter, c, seen(c, people, rng)) for c in views]
        fusion = fuse_and_write([w for w in worlds if w is not None])
        crossing.append([len(fusion.world.tracks), sum(identity_switches(people, t.frames, t.joints[:, 0])
                                                       for t in fusion.world.tracks.values())])
    rng = np.random.default_rng(seed + 3)
    named = []
    for walk in walks[:4]:
        truth, told = room_cameras(3, moved=2)
        tracks = [seen(c, walk[None], rng) for c in truth]  # what the cameras saw, lifted with what the files say
        worlds = [lifted(lifter, c, t) for c, t in zip(told, tracks)]
        named.append(fuse_and_write([w for w in worlds if w is not None]).suspects())
    return {"walks": len(walks), **result, "time offsets, frames (true, found, sd)": offsets,
            "two people crossing, 3 cameras (world tracks, identity switches)": crossing,
            "cam2 placed 0.5 m off: the agreement check names": named}


def play_live(lifter, views: list, tracks: list[dict], frames: int) -> tuple[dict, list[dict]]:
    """Every frame, every camera's people lifted at once and fused: {world id: {frame: joints}} and, per camera,
    {frame: [joints of each track seen]}."""
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


def live(lifter, walks: list[np.ndarray], seed: int = 0, cameras: tuple[int, ...] = CAMERAS) -> dict:
    """The live figures (see the module's text) of ``walks`` lifted by ``lifter``, each seen by each of ``cameras``
    cameras."""
    rng = np.random.default_rng(seed)
    per_person, pelvis, mpjpe = [], [], []
    for count in cameras:
        views, _ = room_cameras(count)
        for walk in walks:
            fused, single = play_live(lifter, views, [seen(c, walk[None], rng) for c in views], len(walk))
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
        views, _ = room_cameras(3)
        fused, _ = play_live(lifter, views, [seen(c, people, rng) for c in views], people.shape[1])
        crossing.append([len(fused), sum(identity_switches(people, sorted(t), np.stack([t[f][0] for f in sorted(t)]))
                                         for t in fused.values())])
    pelvis, mpjpe = np.array(pelvis).reshape(-1, 2), np.array(mpjpe).reshape(-1, 2)
    return {"walks": len(walks), "world people per person (index: people)": np.bincount(per_person).tolist(),
            "scenes": len(mpjpe), "fused pelvis mm": _mean_mm(pelvis[:, 0]),
            "best single camera pelvis mm": _mean_mm(pelvis[:, 1]), "fused abs_mpjpe mm": _mean_mm(mpjpe[:, 0]),
            "best single camera abs_mpjpe mm": _mean_mm(mpjpe[:, 1]),
            "two people crossing, 3 cameras (world people, identity switches)": crossing}
