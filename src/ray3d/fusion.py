"""Several calibrated cameras, one world: each camera's people (its ``World``, lifted as one camera lifts them)
brought onto one clock, the tracks that are the same person joined into one world track, and their joints fused.

- **Clock**: camera c's frame f happens at ``f / fps_c - offset_c`` seconds of the first camera's clock. The
  offsets are given, or found from the people themselves (``find_time_offset``: the shift that best aligns the
  floor tracks two cameras see at once, with its uncertainty). Every track is read on the first camera's frames.
- **Who is who** (``associate``): two tracks of different cameras are one person when, over the frames both see,
  their floor points lie within what their position uncertainties allow (``gate``); a person walking out of one
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
from ray3d.io.world import LiftResult, World

POSE_SD_M = 0.04      # a lifted joint's error about the person's root, each axis
GATE_SIGMAS = 3.0     # how many (combined) standard deviations two cameras' places of one person may differ
GATE_FLOOR_M = 0.25   # plus this: a body is not a point (the pelvis seen from two sides)
MIN_SHARED_FRAMES = 5
BOUNCE_SD_M = 0.015  # how well two cameras agree on the pelvis' height about its mean
VELOCITY_GATE_M_S = 0.6  # one person's floor velocity as two cameras see it differs by less (median)
NEAR_MISS_M = 1.5  # two cameras' tracks walking alike this close, left apart, are checked as one person
UNKNOWN_SD_M = (0.3, 0.05)  # the root's sd along and across its ray taken for a track that states none


@dataclasses.dataclass
class _Track:
    view: int
    name: str
    frames: np.ndarray      # (N,) the first camera's frames it covers
    joints: np.ndarray      # (N, 17, 3)
    sd: np.ndarray          # (N, 2) root sd along and across the ray
    interpolated: np.ndarray  # (N, 17)
    stature_m: float | None

    def at(self, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The rows of ``frames`` this track has, and those frames' positions in it."""
        shared, rows, _ = np.intersect1d(self.frames, frames, return_indices=True)
        return shared, rows


def _on_clock(world: World, view: int, offset_s: float, fps: float) -> list[_Track]:
    """A camera's tracks read on the first camera's frames (linear in time; within each track's span)."""
    tracks = []
    for name, result in world.in_frame("world").tracks.items():
        times = result.frames / result.fps - offset_s
        frames = np.arange(np.ceil(times[0] * fps - 1e-6), np.floor(times[-1] * fps + 1e-6) + 1).astype(int)
        frames = frames[frames >= 0]  # before the first camera's clock starts: not on it
        if not len(frames):
            continue
        at = frames / fps

        def read(values: np.ndarray) -> np.ndarray:
            flat = values.reshape(len(values), -1).astype(np.float64)
            return np.stack([np.interp(at, times, column) for column in flat.T], axis=-1).reshape(
                (len(at),) + values.shape[1:])

        sd = result.position_sd if result.position_sd is not None else np.full((len(times), 2), np.nan)
        stature = (result.refinement or {}).get("stature_m")
        tracks.append(_Track(view, name, frames, read(result.joints), read(sd), read(result.interpolated) > 0.5,
                             None if stature is None else float(stature)))
    return tracks


def _root_sd(track: _Track, rows: np.ndarray) -> np.ndarray:
    """(N, 2) the root's sd along and across its ray (``UNKNOWN_SD_M`` where the track states none)."""
    return np.where(np.isfinite(track.sd[rows]), track.sd[rows], UNKNOWN_SD_M)


def _along_ray(points: np.ndarray, centre: np.ndarray, sd: np.ndarray) -> np.ndarray:
    """(..., D, D) covariances of (..., D) points seen from ``centre``: ``sd[..., 0]`` along the ray to each point,
    ``sd[..., 1]`` across it."""
    ray = points - centre
    ray /= np.maximum(np.linalg.norm(ray, axis=-1, keepdims=True), 1e-9)
    along = ray[..., :, None] * ray[..., None, :]
    return (sd[..., 0, None, None] ** 2 * along
            + sd[..., 1, None, None] ** 2 * (np.eye(points.shape[-1]) - along))


def _floor_velocity(track: _Track, rows: np.ndarray, fps: float) -> np.ndarray:
    """(N, 2) the floor velocity at ``rows``, over half a second each side (m/s)."""
    half = max(1, int(round(fps / 2)))
    before, after = np.clip(rows - half, 0, len(track.frames) - 1), np.clip(rows + half, 0, len(track.frames) - 1)
    span = np.maximum(track.frames[after] - track.frames[before], 1) / fps
    return (track.joints[after, 0, :2] - track.joints[before, 0, :2]) / span[:, None]


def _pair_distance(a: _Track, b: _Track, fps: float = 10.0) -> tuple[float, float, int]:
    """Median floor distance between two tracks over their shared frames, the gate for it (infinitely far where
    they walk differently: two people passing close by), the frames shared."""
    shared, rows_a, rows_b = np.intersect1d(a.frames, b.frames, return_indices=True)
    if len(shared) < MIN_SHARED_FRAMES:
        return np.inf, 0.0, len(shared)
    gap = np.linalg.norm(a.joints[rows_a, 0, :2] - b.joints[rows_b, 0, :2], axis=-1)
    larger_a, larger_b = _root_sd(a, rows_a).max(axis=-1), _root_sd(b, rows_b).max(axis=-1)
    allowed = GATE_SIGMAS * np.hypot(larger_a, larger_b) + GATE_FLOOR_M
    pace = np.linalg.norm(_floor_velocity(a, rows_a, fps) - _floor_velocity(b, rows_b, fps), axis=-1)
    if np.median(pace) > VELOCITY_GATE_M_S:
        return np.inf, float(np.median(allowed)), len(shared)
    return float(np.median(gap)), float(np.median(allowed)), len(shared)


def gate_m(a_sd: float, b_sd: float) -> float:
    """The largest floor distance at which two cameras' places of one person still agree."""
    return GATE_SIGMAS * float(np.hypot(a_sd, b_sd)) + GATE_FLOOR_M


def associate(tracks: list[_Track], handover_s: float = 2.0, fps: float = 10.0) -> list[list[int]]:
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
            distance, allowed, _ = _pair_distance(tracks[i], tracks[j], fps)
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
            if miss <= GATE_FLOOR_M + 0.5 * gap_s + 0.3:
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


def _group_floor(tracks: list[_Track], members: list[int], frame: int) -> np.ndarray:
    """A group's floor point at the frame of its members nearest ``frame`` (the mean where several have it)."""
    nearest = min((abs(f - frame), f) for i in members for f in (tracks[i].frames[0], tracks[i].frames[-1],
                                                                  *tracks[i].frames[tracks[i].frames <= frame][-1:]))[1]
    points = [tracks[i].joints[rows, 0, :2] for i in members for _, rows in [tracks[i].at(np.array([nearest]))]
              if len(rows)]
    return np.mean(np.concatenate(points), axis=0)


def _covariances(track: _Track, rows: np.ndarray, camera_center: np.ndarray) -> np.ndarray:
    """(N, 17, 3, 3) each joint's covariance from this camera in each frame: long along the joint's own ray (the
    root's sd along its ray) and narrow across it (the root's sd across), plus the pose's own error."""
    sd = np.repeat(_root_sd(track, rows)[:, None], track.joints.shape[1], axis=1)
    return _along_ray(track.joints[rows], camera_center, sd) + POSE_SD_M ** 2 * np.eye(3)


def fuse(tracks: list[_Track], members: list[int], centers: list[np.ndarray], fps: float,
         cameras: int) -> LiftResult:
    """One person's tracks from several cameras -> one ``LiftResult`` on the first camera's frames: joints fused
    where several see them (the information-weighted mean), ``seen_by`` (T, cameras) and the root's sd
    (the fused covariance's largest and smallest horizontal spread)."""
    frames = np.unique(np.concatenate([tracks[i].frames for i in members]))
    information = np.zeros((len(frames), 17, 3, 3))
    weighted = np.zeros((len(frames), 17, 3))
    seen_by = np.zeros((len(frames), cameras), bool)
    interpolated = np.ones((len(frames), 17), bool)
    statures, weights = [], []
    for i in members:
        track = tracks[i]
        shared, rows, at = np.intersect1d(track.frames, frames, return_indices=True)
        inverse = np.linalg.inv(_covariances(track, rows, centers[track.view]))
        information[at] += inverse
        weighted[at] += np.einsum("nkij,nkj->nki", inverse, track.joints[rows])
        seen_by[at, track.view] = True
        interpolated[at] &= track.interpolated[rows]
        if track.stature_m is not None:
            statures.append(track.stature_m)
            weights.append(len(rows))
    covariance = np.linalg.inv(information)
    joints = np.einsum("nkij,nkj->nki", covariance, weighted)
    spread = np.sqrt(np.clip(np.linalg.eigvalsh(covariance[:, 0, :2, :2]), 0.0, None))  # the root's
    refinement = {"stature_m": round(float(np.average(statures, weights=weights)), 4)} if statures else None
    return dataclasses.replace(LiftResult(joints, interpolated, fps, frames, refinement=refinement,
                                          position_sd=spread[:, ::-1].copy()), seen_by=seen_by)


def _floor_covariance(track: _Track, rows: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """(N, 2, 2) the floor point's covariance from one camera: long along its ray, narrow across it."""
    return _along_ray(track.joints[rows, 0, :2], centre, _root_sd(track, rows))


def _floor_mahalanobis(a: _Track, b: _Track, centres: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """(N,) the Mahalanobis distance between two tracks' floor points in each of their shared frames: a camera's
    error along its ray (its depth bias, which would pass for a time shift of a person walking along it) counts
    little, its precise place across the ray much."""
    _, rows_a, rows_b = np.intersect1d(a.frames, b.frames, return_indices=True)
    covariance = _floor_covariance(a, rows_a, centres[0]) + _floor_covariance(b, rows_b, centres[1])
    difference = a.joints[rows_a, 0, :2] - b.joints[rows_b, 0, :2]
    floor = np.einsum("ni,nij,nj->n", difference, np.linalg.inv(covariance), difference)
    # The pelvis' rise and fall with each step, about each track's own mean height: no camera's bias moves it.
    bounce = a.joints[rows_a, 0, 2] - a.joints[rows_a, 0, 2].mean() - b.joints[rows_b, 0, 2] + b.joints[rows_b, 0, 2].mean()
    return np.sqrt(floor + (bounce / BOUNCE_SD_M) ** 2)


def find_time_offset(reference: World, other: World, max_offset_s: float = 2.0) -> tuple[float, float]:
    """The offset (seconds; ``other``'s frame f happens at f / fps - offset on the reference's clock) that best
    aligns the floor tracks both cameras see at once, searched in steps of a frame of the reference within
    +-``max_offset_s``, refined to a fraction of a frame by a parabola through the best three; and how sure it is
    (half the spread of the shifts scoring within 10 % of the best). Refused when no shift lets the cameras share a person."""
    fps = reference.fps
    steps = np.arange(-int(round(max_offset_s * fps)), int(round(max_offset_s * fps)) + 1)
    first = _on_clock(reference, 0, 0.0, fps)
    centres = (reference.camera.center[:2], other.camera.center[:2])
    scores = []
    for step in steps:
        shifted = _on_clock(other, 1, step / fps, fps)
        distances = []
        for a in first:
            for b in shifted:
                distance, allowed, _ = _pair_distance(a, b, fps)
                if distance <= 2 * allowed:
                    distances.append(_floor_mahalanobis(a, b, centres))
        # Every shared frame weighs alike: a short overlap at the end of a broken track counts for few frames.
        scores.append(np.mean(np.concatenate(distances)) if distances else np.inf)
    scores = np.array(scores)
    if not np.isfinite(scores).any():
        raise InputError("cameras: no person is seen by both at once at any offset within "
                         f"{max_offset_s:g} s; give the offset", ("offsets",))
    best = int(np.argmin(scores))
    shift = float(steps[best])
    curvature = np.inf
    if 0 < best < len(steps) - 1 and np.isfinite(scores[best - 1:best + 2]).all():
        left, middle, right = scores[best - 1:best + 2]
        curvature = left - 2 * middle + right
        if curvature > 0:
            shift += 0.5 * (left - right) / curvature
    # How sure: half the spread of the shifts that score within 10 % of the best (a flat score, as for people
    # standing still, is a wide spread), and no less than the half frame the search resolves.
    near = steps[scores <= 1.1 * scores[best]]
    sd_frames = max(0.5, (near.max() - near.min()) / 2)
    return shift / fps, sd_frames / fps


AGREEMENT_SIGMAS = 3.0  # two cameras disagree when a person's places differ by more, in combined sds (median)


def _near_misses(tracks: list[_Track], groups: list[list[int]], fps: float) -> list[tuple[int, int]]:
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
            pace = np.linalg.norm(_floor_velocity(a, rows_a, fps) - _floor_velocity(b, rows_b, fps), axis=-1)
            distance = float(np.median(np.linalg.norm(a.joints[rows_a, 0, :2] - b.joints[rows_b, 0, :2], axis=-1)))
            if np.median(pace) <= VELOCITY_GATE_M_S and distance <= NEAR_MISS_M and \
                    distance < best.get((i, b.view), (np.inf,))[0]:
                best[i, b.view] = (distance, j)
    # Mutual nearest, camera pair by camera pair.
    return [(i, j) for (i, _), (_, j) in best.items() if i < j and best.get((j, tracks[i].view), (0, -1))[1] == i]


def camera_agreement(tracks: list[_Track], groups: list[list[int]], names: list[str],
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
        covariance = (_floor_covariance(a, rows_a, centres[a.view][:2])
                      + _floor_covariance(b, rows_b, centres[b.view][:2]))
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
                max_offset_s: float = 2.0, handover_s: float = 2.0) -> Fusion:
    """Several cameras' worlds (each lifted from one camera) -> one world with one track per person. Offsets
    given (seconds, one per camera, the first 0), found from the people (``find_offsets``), or 0."""
    if len(worlds) < 2:
        raise InputError("cameras: fusing needs two or more cameras' worlds", ("cameras",))
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
    tracks = [t for k, world in enumerate(worlds) for t in _on_clock(world, k, offsets_s[k], fps)]
    groups = associate(tracks, handover_s, fps)
    centers = [world.camera.center for world in worlds]
    fused = {str(n): fuse(tracks, g, centers, fps, len(worlds)) for n, g in enumerate(groups)}
    members = {str(n): [f"{names[tracks[i].view]}:{tracks[i].name}" for i in g] for n, g in enumerate(groups)}
    world = World(fused, worlds[0].camera, worlds[0].model, cameras=tuple(w.camera for w in worlds))
    return Fusion(world, list(offsets_s), sds, members, camera_agreement(tracks, groups, names, centers, fps))
