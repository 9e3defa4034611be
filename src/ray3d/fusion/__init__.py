"""Several calibrated cameras, one world: each camera's people (its ``World``, lifted as one camera lifts them)
brought onto one clock, the tracks that are the same person joined into one world track, and their joints fused.

- **Clock** (``ray3d.fusion.clock``): camera c's frame f happens at ``f / fps_c - offset_c`` seconds of the first
  camera's clock. The offsets are given, or found from the people themselves (``find_time_offset``: the shift that best
  aligns the bodies of the people two cameras see at once, with its uncertainty). Every track is read on the first
  camera's frames.
- **Who is who** (``associate``): two tracks of different cameras are one person when, over the frames both see,
  their floor points lie within what their position uncertainties allow (``pair_distance``); a person walking out of one
  camera's view and into another's within ``handover_s`` is kept when the new track starts where the old one's
  walk would have taken them. A camera never sees one person as two tracks at once, so no join puts two tracks of
  one camera in one person at the same moment: two people crossing stay apart.
- **Fusion** (``fuse``): where several cameras see a person, each joint is the information-weighted mean of the
  cameras' (each camera's covariance long along that joint's ray, by the root's uncertainty along it, and narrow
  across it): where the rays meet at an angle this is the joint rays' triangulation with the lifted bodies as the
  prior, where they are nearly parallel it is their average weighted by distance.
- **Agreement** (``camera_agreement``): per camera pair, the median distance between one person's floor points as
  each camera places them, against what their uncertainties allow: the first sign of a wrong calibration.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ray3d.errors import InputError
from ray3d.fusion.clock import find_time_offset
from ray3d.fusion.tracks import (
    MIN_SHARED_FRAMES,
    VELOCITY_GATE_M_S,
    CameraTrack,
    floor_velocity,
    handover_reach_m,
    on_clock,
    pair_distance,
)
from ray3d.geometry.uncertainty import information_weighted, root_spread
from ray3d.io.world import LiftResult, World

NEAR_MISS_M = 1.5  # two cameras' tracks walking alike this close, left apart, are checked as one person


def associate(tracks: list[CameraTrack], handover_s: float = 2.0, fps: float = 10.0) -> list[list[int]]:
    """Groups of indices into ``tracks`` that are one person each (see the module's note)."""
    group = list(range(len(tracks)))

    def root(i: int) -> int:
        while group[i] != i:
            group[i] = group[group[i]]
            i = group[i]
        return i

    def members(r: int) -> list[int]:
        return [i for i in range(len(tracks)) if root(i) == r]

    def clash(a: int, b: int) -> bool:
        """Whether joining the groups of a and b would make one camera see one person twice at once."""
        for i in members(root(a)):
            for j in members(root(b)):
                if tracks[i].view == tracks[j].view and len(np.intersect1d(tracks[i].frames, tracks[j].frames)):
                    return True
        return False

    candidates = []
    for i in range(len(tracks)):
        for j in range(i + 1, len(tracks)):
            if tracks[i].view == tracks[j].view:
                continue
            distance, allowed, _ = pair_distance(tracks[i], tracks[j], fps)
            if distance <= allowed:
                candidates.append((distance / allowed, i, j))
    for _, i, j in sorted(candidates):
        if root(i) != root(j) and not clash(i, j):
            group[root(j)] = root(i)
    # Hand-overs: a group that ends, and one that starts within handover_s where the first's walk leads.
    spans = {}
    for r in {root(i) for i in range(len(tracks))}:
        frames = np.concatenate([tracks[i].frames for i in members(r)])
        spans[r] = (frames.min(), frames.max())
    links = []
    for a, (start_a, end_a) in spans.items():
        last = _group_floor(tracks, members(a), end_a)
        before = _group_floor(tracks, members(a), max(start_a, end_a - int(fps)))
        velocity = (last - before) / max((end_a - max(start_a, end_a - int(fps))) / fps, 1e-6)
        for b, (start_b, end_b) in spans.items():
            gap_s = (start_b - end_a) / fps
            # A hand-over: b starts after a and lasts beyond it, both seen together for too few frames to join.
            if b == a or not (start_b > start_a and end_b > end_a and -MIN_SHARED_FRAMES / fps < gap_s <= handover_s):
                continue
            expected = last + velocity * gap_s if gap_s > 0 else _group_floor(tracks, members(a), start_b)
            miss = float(np.linalg.norm(_group_floor(tracks, members(b), start_b) - expected))
            if miss <= handover_reach_m(gap_s):
                links.append((miss, a, b))
    used_ends, used_starts = set(), set()
    for _, a, b in sorted(links):
        if a in used_ends or b in used_starts or root(a) == root(b) or clash(a, b):
            continue
        used_ends.add(a)
        used_starts.add(b)
        group[root(b)] = root(a)
    found = {}
    for i in range(len(tracks)):
        found.setdefault(root(i), []).append(i)
    return sorted(found.values(), key=lambda g: min(tracks[i].frames[0] for i in g))


def _group_floor(tracks: list[CameraTrack], members: list[int], frame: int) -> np.ndarray:
    """A group's floor point at the frame of its members nearest ``frame`` (the mean where several have it)."""
    nearest = min((abs(f - frame), f) for i in members for f in (tracks[i].frames[0], tracks[i].frames[-1],
                                                                  *tracks[i].frames[tracks[i].frames <= frame][-1:]))[1]
    points = [tracks[i].joints[rows, 0, :2] for i in members for _, rows in [tracks[i].at(np.array([nearest]))]
              if len(rows)]
    return np.mean(np.concatenate(points), axis=0)




def fuse(tracks: list[CameraTrack], members: list[int], centers: list[np.ndarray], fps: float,
         cameras: int) -> LiftResult:
    """One person's tracks from several cameras -> one ``LiftResult`` on the first camera's frames: joints fused
    where several see them (the information-weighted mean), ``seen_by`` (T, cameras) and the root's sd
    (the fused covariance's largest and smallest horizontal spread)."""
    frames = np.unique(np.concatenate([tracks[i].frames for i in members]))
    joints = np.zeros((len(members), len(frames), 17, 3))
    covariances = np.broadcast_to(np.eye(3), (len(members), len(frames), 17, 3, 3)).copy()
    seen = np.zeros((len(members), len(frames)), bool)
    seen_by = np.zeros((len(frames), cameras), bool)
    interpolated = np.ones((len(frames), 17), bool)
    statures, weights = [], []
    for m, i in enumerate(members):
        track = tracks[i]
        shared, rows, at = np.intersect1d(track.frames, frames, return_indices=True)
        joints[m, at], covariances[m, at] = track.joints[rows], track.joint_covariances(centers[track.view], rows)
        seen[m, at] = True
        seen_by[at, track.view] = True
        interpolated[at] &= track.interpolated[rows]
        if track.stature_m is not None:
            statures.append(track.stature_m)
            weights.append(len(rows))
    joints, covariance = information_weighted(joints, covariances, np.repeat(seen[..., None], 17, axis=-1))
    refinement = {"stature_m": round(float(np.average(statures, weights=weights)), 4)} if statures else None
    return dataclasses.replace(LiftResult(joints, interpolated, fps, frames, refinement=refinement,
                                          position_sd=root_spread(covariance)), seen_by=seen_by)


AGREEMENT_SIGMAS = 3.0  # two cameras disagree when a person's places differ by more, in combined sds (median)


def _near_misses(tracks: list[CameraTrack], groups: list[list[int]], fps: float) -> list[tuple[int, int]]:
    """Pairs of tracks of different cameras left apart that are likely one person all the same: seen at once,
    walking alike, within ``NEAR_MISS_M`` of each other, and each the other's nearest such track (a camera whose
    file puts it half a metre off places everybody beyond the gate)."""
    person = {i: k for k, members in enumerate(groups) for i in members}

    def seen_by(i: int, view: int) -> bool:
        """Whether track i's person is seen by camera ``view`` at any of track i's frames."""
        return any(tracks[k].view == view and len(np.intersect1d(tracks[k].frames, tracks[i].frames))
                   for k in groups[person[i]])

    best: dict[tuple[int, int], tuple[float, int]] = {}
    for i, a in enumerate(tracks):
        for j, b in enumerate(tracks):
            # Only a person whom the other camera does not see as anybody then (two walking together are not).
            if a.view == b.view or person[i] == person[j] or seen_by(i, b.view) or seen_by(j, a.view):
                continue
            shared, rows_a, rows_b = np.intersect1d(a.frames, b.frames, return_indices=True)
            if len(shared) < MIN_SHARED_FRAMES:
                continue
            pace = np.linalg.norm(floor_velocity(a, rows_a, fps) - floor_velocity(b, rows_b, fps), axis=-1)
            distance = float(np.median(np.linalg.norm(a.joints[rows_a, 0, :2] - b.joints[rows_b, 0, :2], axis=-1)))
            if np.median(pace) <= VELOCITY_GATE_M_S and distance <= NEAR_MISS_M and \
                    distance < best.get((i, b.view), (np.inf,))[0]:
                best[i, b.view] = (distance, j)
    # Mutual nearest, camera pair by camera pair.
    return [(i, j) for (i, _), (_, j) in best.items() if i < j and best.get((j, tracks[i].view), (0, -1))[1] == i]


def camera_agreement(tracks: list[CameraTrack], groups: list[list[int]], names: list[str],
                     centres: list[np.ndarray], fps: float = 10.0) -> list[dict]:
    """Per pair of cameras that saw someone at once: the median distance between a person's floor points as each
    places them (metres, over every shared frame), the same in combined standard deviations (each camera's
    uncertainty long along its ray, narrow across it), the frames, and whether it exceeds ``AGREEMENT_SIGMAS``.
    A person counts whether joined or a near miss (``_near_misses``): a camera too far off to be joined is the one
    most to be named."""
    pairs = [(i, j) for members in groups for x, i in enumerate(members) for j in members[x + 1:]]
    gaps: dict[tuple[int, int], list] = {}
    for i, j in pairs + _near_misses(tracks, groups, fps):
        a, b = sorted((tracks[i], tracks[j]), key=lambda t: t.view)
        if a.view == b.view:
            continue
        _, rows_a, rows_b = np.intersect1d(a.frames, b.frames, return_indices=True)
        if not len(rows_a):  # one person, seen by the two cameras one after the other
            continue
        difference = a.joints[rows_a, 0, :2] - b.joints[rows_b, 0, :2]
        covariance = a.floor_covariance(centres[a.view], rows_a) + b.floor_covariance(centres[b.view], rows_b)
        sigmas = np.sqrt(np.einsum("ni,nij,nj->n", difference, np.linalg.inv(covariance), difference))
        entry = gaps.setdefault((a.view, b.view), [[], []])
        entry[0] += np.linalg.norm(difference, axis=-1).tolist()
        entry[1] += sigmas.tolist()
    report = []
    for (a, b), (gap, sigmas) in sorted(gaps.items()):
        median = float(np.median(sigmas))
        report.append({"cameras": [names[a], names[b]], "median_distance_m": round(float(np.median(gap)), 3),
                       "median_sigmas": round(median, 2), "frames": len(gap), "disagree": median > AGREEMENT_SIGMAS})
    return report


@dataclasses.dataclass
class Fusion:
    """The fused world (the first camera's clock and frame numbers; ``World.cameras`` every camera), the offsets
    used (seconds, the first camera 0) with their uncertainties (0 where given), which camera tracks each world
    track joined ({world track: ["camera:track", ...]}) and the cameras' agreement."""

    world: World
    offsets_s: list[float]
    offset_sd_s: list[float]
    members: dict[str, list[str]]
    agreement: list[dict]

    def suspects(self) -> list[str]:
        """The cameras that disagree with every other camera they share people with (the likeliest wrong
        calibration), or, between two cameras only, both."""
        disagreeing = [set(entry["cameras"]) for entry in self.agreement if entry["disagree"]]
        counts: dict[str, int] = {}
        for pair in disagreeing:
            for name in pair:
                counts[name] = counts.get(name, 0) + 1
        return sorted(name for name, n in counts.items() if n == max(counts.values(), default=0)) if counts else []


def fuse_worlds(worlds: list[World], offsets_s: list[float] | None = None, find_offsets: bool = False,
                max_offset_s: float = 2.0, handover_s: float = 2.0,
                groups: dict[str, list[tuple[int, str]]] | None = None) -> Fusion:
    """Several cameras' worlds (each lifted from one camera) -> one world with one track per person. Offsets
    given (seconds, one per camera, the first 0), found from the people (``find_offsets``), or 0. Who is who is
    found (``associate``), or given as ``groups`` ({person: [(camera index, track), ...]}, as a live run joined
    them as it went: ``fusion.live.LiveFusion.joined``): then the world's tracks are those people, by their names,
    and a track in no group is left out."""
    if len(worlds) < 2:
        raise InputError("cameras: fusing needs two or more cameras' worlds", ("cameras",))
    if not all(isinstance(world, World) for world in worlds):
        raise InputError("worlds: each a World (io.world.read_world)", ("worlds",))
    names = [world.camera.name or f"camera {k}" for k, world in enumerate(worlds)]
    if len(set(names)) < len(names):
        names = [f"{k}:{name}" for k, name in enumerate(names)]
    sds = [0.0] * len(worlds)
    if offsets_s is None:
        offsets_s = [0.0] * len(worlds)
        if find_offsets:
            for k in range(1, len(worlds)):
                offsets_s[k], sds[k] = find_time_offset(worlds[0], worlds[k], max_offset_s)
    elif len(offsets_s) != len(worlds):
        raise InputError(f"offsets: {len(offsets_s)} given for {len(worlds)} cameras", ("offsets",))
    fps = worlds[0].fps
    tracks = [t for k, world in enumerate(worlds) for t in on_clock(world, k, offsets_s[k], fps)]
    if groups is None:
        people = {str(n): g for n, g in enumerate(associate(tracks, handover_s, fps))}
    else:
        index = {(t.view, t.name): i for i, t in enumerate(tracks)}
        try:
            chosen = {str(person): [index[key] for key in map(tuple, members) if key in index]
                      for person, members in groups.items()}
        except (AttributeError, TypeError):
            raise InputError("groups: {person: [(camera index, track), ...]}", ("groups",)) from None
        kept = sorted(i for g in chosen.values() for i in g)
        renumbered = {i: k for k, i in enumerate(kept)}
        tracks = [tracks[i] for i in kept]
        people = {person: [renumbered[i] for i in g] for person, g in chosen.items() if g}
    centers = [world.camera.center for world in worlds]
    fused = {n: fuse(tracks, g, centers, fps, len(worlds)) for n, g in people.items()}
    members = {n: [f"{names[tracks[i].view]}:{tracks[i].name}" for i in g] for n, g in people.items()}
    world = World(fused, worlds[0].camera, worlds[0].model, cameras=tuple(w.camera for w in worlds))
    return Fusion(world, list(offsets_s), sds, members,
                  camera_agreement(tracks, list(people.values()), names, centers, fps))
