"""Who is who over short gaps: a track that ends (its person lost behind somebody, or missed by the detector for
longer than the tracker waits) is kept as a candidate for ``within_s`` seconds; a track that starts after it, where
its walk would have taken it (``fusion.tracks.handover_reach_m`` of the extrapolated place), heading the way it
was, in clothes of its colours, is the same person: one identity, the frames between unseen.

The rules hold for every pair: a track never continues one it overlaps in time (one person is never two at once),
nor one its start is out of walking reach of, nor one whose clothes are unlike its own (two people crossing with
their identities swapped). Where several could continue, the likeliest (the nearest to the walk's prediction, in
units of the reach, plus the clothes' difference) is taken."""

from __future__ import annotations

import dataclasses

import numpy as np

from ray3d.fusion.tracks import handover_reach_m
from ray3d.temporal import velocity
from ray3d.video.tracking import COLOUR_GATE, Track, colour_distance

REJOIN_WITHIN_S = 3.0   # the longest gap across which a person is taken up again
WALK_WINDOW_S = 1.0     # a track's walk (its velocity) at its end and start, over this much of it
HEADING_GATE_M_S = 1.5  # two walks that differ by more (their velocities) are two people, moving


@dataclasses.dataclass(frozen=True)
class Rejoin:
    """``joined`` continued ``identity`` after ``gap_s`` seconds unseen (from frame ``after_frame``): its start
    ``miss_m`` from where the walk led, within ``reach_m``, clothes ``unlike`` (0 the same, 1 nothing in common)."""

    identity: str
    joined: str
    after_frame: int
    gap_s: float
    miss_m: float
    reach_m: float
    unlike: float

    def to_dict(self) -> dict:
        return {k: (round(v, 3) if isinstance(v, float) else v) for k, v in dataclasses.asdict(self).items()}


def _walk(track: Track, fps: float, at_end: bool) -> tuple[np.ndarray, np.ndarray, float]:
    """The floor point (2,) and velocity (2,) at the track's end (or start), and the seconds it was read over."""
    times = np.asarray(track.frames, dtype=np.float64) / fps
    points = np.stack(track.floor)
    seen = np.isfinite(points).all(axis=1)
    times, points = times[seen], points[seen]
    if not len(points):
        return np.full(2, np.nan), np.zeros(2), 0.0
    if at_end:
        moved, span = velocity(times, points, WALK_WINDOW_S, 0.0)
        return points[-1], moved[-1], float(span[-1])
    moved, span = velocity(times, points, 0.0, WALK_WINDOW_S)
    return points[0], moved[0], float(span[0])


def rejoin_tracks(tracks: list[Track], fps: float,
                  within_s: float = REJOIN_WITHIN_S) -> tuple[list[Track], list[Rejoin]]:
    """``tracks`` (a tracker's, each in frame order) -> one track per identity (the first track's id, its
    continuations' frames appended) and every re-join made. ``within_s`` 0: none."""
    identities: list[Track] = []
    rejoins: list[Rejoin] = []
    for track in sorted(tracks, key=lambda t: t.frames[0]):
        start, start_walk, start_span = _walk(track, fps, at_end=False)
        best = None
        for identity in identities:
            gap_s = (track.frames[0] - identity.frames[-1]) / fps
            if not 0 < gap_s <= within_s or not np.isfinite(start).all():
                continue
            end, end_walk, end_span = _walk(identity, fps, at_end=True)
            if not np.isfinite(end).all():
                continue
            # A walk read over too short a stretch is the detector's jitter as much as a heading.
            if min(start_span, end_span) >= WALK_WINDOW_S / 2 and \
                    np.linalg.norm(start_walk - end_walk) > HEADING_GATE_M_S:
                continue
            miss, reach = float(np.linalg.norm(start - (end + end_walk * gap_s))), handover_reach_m(gap_s)
            unlike = 0.5 if identity.colour is None or track.colour is None else \
                colour_distance(identity.colour, track.colour)
            if miss > reach or unlike >= COLOUR_GATE:
                continue
            score = miss / reach + unlike
            if best is None or score < best[0]:
                best = (score, identity, Rejoin(identity.id, track.id, identity.frames[-1], gap_s, miss, reach,
                                                unlike))
        if best is None:
            identities.append(dataclasses.replace(track, frames=list(track.frames),
                                                  detections=list(track.detections), floor=list(track.floor)))
            continue
        _, identity, rejoin = best
        identity.frames += track.frames
        identity.detections += track.detections
        identity.floor += track.floor
        identity.colour = track.colour if track.colour is not None else identity.colour
        rejoins.append(rejoin)
    return identities, rejoins
