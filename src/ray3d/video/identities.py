"""Who is who over short gaps: a track that ends (its person lost behind somebody, or missed by the detector for
longer than the tracker waits) is kept as a candidate for ``within_s`` seconds; a track that starts after it, where
its walk would have taken it, heading a way it could have turned to, in clothes of its colours (jacket and
trousers), is the same person: one identity, the frames between unseen.

"Where its walk would have taken it" is a gate in standard deviations: over the gap the person is taken to have
walked at the mean of the two walks, the one at the end and the one at the start (a steady turn: who slowed down,
stopped or turned back behind somebody is where that mean leads), and the gate is the walk's own allowance
(``fusion.tracks.handover_reach_m``) widened by what the floor points' covariances make uncertain: the place where
the one track ended and the other started, and the velocities read from them carried over the gap. A far person's
floor point moves by a metre with a pixel, and their walk is read that loosely; a near person's is not. The heading
gate is read the same way, and widens with the gap by what a walker can turn in that time (``TURN_M_S2``): nobody
walks back the other way a second later, but after two or three seconds behind somebody they may.

An identity's clothes are the mean of its tracks' colours, each weighted by its frames: a short track on a box
read half off somebody beside them does not lend the person that somebody's colours.

The rules hold for every pair: a track never continues one it overlaps in time (one person is never two at once),
nor one its start is out of walking reach of, nor one whose clothes are unlike its own (two people crossing with
their identities swapped). Where several could continue, the likeliest (the nearest to the walk's prediction, in
standard deviations, plus the clothes' difference) is taken."""

from __future__ import annotations

import dataclasses

import numpy as np

from ray3d.fusion.tracks import handover_reach_m
from ray3d.temporal import velocity
from ray3d.video.clothes import COLOUR_GATE, colour_distance
from ray3d.video.track import Track

REJOIN_WITHIN_S = 3.0   # the longest gap across which a person is taken up again
WALK_WINDOW_S = 1.0     # a track's walk (its velocity) at its end and start, over this much of it
HEADING_GATE_M_S = 1.5  # two walks that differ by more (their velocities) are two people, moving
TURN_M_S2 = 1.0         # how fast a walker changes their velocity (turns, stops, sets off): the gate widens by it
WALK_SPEED_SD_M_S = 1.5  # how little a walk read from one point says of its velocity
_SIGMAS = 3.03  # the gates in standard deviations: chi-square, 2 degrees of freedom, 99 %


@dataclasses.dataclass(frozen=True)
class Rejoin:
    """``joined`` continued ``identity`` after ``gap_s`` seconds unseen (from frame ``after_frame``): its start
    ``miss_m`` from where the walk led, within ``reach_m`` (the gate's reach that way), clothes ``unlike`` (0 the
    same, 1 nothing in common)."""

    identity: str
    joined: str
    after_frame: int
    gap_s: float
    miss_m: float
    reach_m: float
    unlike: float

    def to_dict(self) -> dict:
        return {k: (round(v, 3) if isinstance(v, float) else v) for k, v in dataclasses.asdict(self).items()}


@dataclasses.dataclass(frozen=True)
class _Walk:
    """Where a track's walk was at one of its ends and how it went: the floor point (2,) and velocity (2,) with
    their covariances (2, 2) (from the floor points' own), read over ``span_s`` seconds."""

    point: np.ndarray
    point_noise: np.ndarray
    velocity: np.ndarray
    velocity_noise: np.ndarray
    span_s: float


def _walk(track: Track, fps: float, at_end: bool) -> _Walk | None:
    """The walk at the track's end (or start), or None where no floor point of it was placed."""
    times = np.asarray(track.frames, dtype=np.float64) / fps
    points = np.stack(track.floor)
    noise = np.stack(track.floor_noise) if track.floor_noise else np.zeros((len(points), 2, 2))
    seen = np.isfinite(points).all(axis=1)
    times, points, noise = times[seen], points[seen], noise[seen]
    if not len(points):
        return None
    before, after = (WALK_WINDOW_S, 0.0) if at_end else (0.0, WALK_WINDOW_S)
    moved, span = velocity(times, points, before, after)
    at = -1 if at_end else 0
    # The velocity is the difference of two points span_s apart: its covariance is theirs over span_s squared.
    other = np.searchsorted(times, times[at] - span[at] - 1e-9) if at_end else \
        np.searchsorted(times, times[at] + span[at] - 1e-9)
    other = int(np.clip(other, 0, len(times) - 1))
    velocity_noise = (noise[at] + noise[other]) / max(float(span[at]), 1e-9) ** 2 if span[at] > 0 else \
        np.eye(2) * WALK_SPEED_SD_M_S ** 2
    return _Walk(points[at], noise[at], moved[at], velocity_noise, float(span[at]))


def _steady(walk: _Walk) -> bool:
    """Whether the walk was read over enough of its track to be a walk: over less, it is the detector's jitter as
    much as a heading."""
    return walk.span_s >= WALK_WINDOW_S / 2


def _mahalanobis_squared(difference: np.ndarray, covariance: np.ndarray) -> float:
    return float(difference @ np.linalg.solve(covariance, difference))


def continuation(identity: Track, track: Track, fps: float, within_s: float = REJOIN_WITHIN_S
                 ) -> tuple[float, Rejoin] | None:
    """Whether ``track`` continues ``identity`` (it starts after the identity's last frame, within ``within_s``):
    (its score, the lower the likelier: how far from where the walk led, in gates, plus how unlike the clothes;
    the re-join) or None where a gate says they are two people."""
    gap_s = (track.frames[0] - identity.frames[-1]) / fps
    if not 0 < gap_s <= within_s:
        return None
    start, end = _walk(track, fps, at_end=False), _walk(identity, fps, at_end=True)
    if start is None or end is None:
        return None
    # Each gate is the walk's own allowance widened by how uncertain the floor points make its reading.
    turned = _mahalanobis_squared(start.velocity - end.velocity, start.velocity_noise + end.velocity_noise
                                  + np.eye(2) * ((HEADING_GATE_M_S + TURN_M_S2 * gap_s) / _SIGMAS) ** 2)
    if _steady(start) and _steady(end) and turned > _SIGMAS ** 2:
        return None
    # Unseen, they walked at the mean of the two walks (a steady turn), of those read long enough to be walks.
    walks = [walk for walk in (end, start) if _steady(walk)] or [end]
    mean_velocity = sum(walk.velocity for walk in walks) / len(walks)
    mean_velocity_noise = sum(walk.velocity_noise for walk in walks) / len(walks) ** 2
    miss_vector = start.point - (end.point + mean_velocity * gap_s)
    reach = handover_reach_m(gap_s)
    spread = end.point_noise + mean_velocity_noise * gap_s ** 2 + start.point_noise
    missed = _mahalanobis_squared(miss_vector, spread + np.eye(2) * (reach / _SIGMAS) ** 2)
    unlike = 0.5 if identity.colour is None or track.colour is None else colour_distance(identity.colour, track.colour)
    if missed > _SIGMAS ** 2 or unlike >= COLOUR_GATE:
        return None
    miss = float(np.linalg.norm(miss_vector))
    # The gate's reach along the miss: how far that way the start could have been and still be them.
    reach_along = _SIGMAS * miss / np.sqrt(missed) if missed > 0 else reach
    return (float(np.sqrt(missed) / _SIGMAS + unlike),
            Rejoin(identity.id, track.id, identity.frames[-1], gap_s, miss, float(reach_along), unlike))


def likeliest_continued(identities: list[Track], track: Track, fps: float, within_s: float = REJOIN_WITHIN_S
                        ) -> tuple[Track, Rejoin] | None:
    """The identity ``track`` continues (``continuation``'s likeliest of ``identities``) and the re-join, or None."""
    scored = [(found, identity) for identity in identities
              if (found := continuation(identity, track, fps, within_s)) is not None]
    if not scored:
        return None
    (_, rejoin), identity = min(scored, key=lambda pair: pair[0][0])
    return identity, rejoin


def join(identity: Track, track: Track, rejoin: Rejoin) -> None:
    """``track``'s frames appended to ``identity``'s, its clothes' colours averaged in by frames, its walk the latest,
    the re-join kept."""
    if track.colour is not None:
        seen, now = len(identity.frames), len(track.frames)
        identity.colour = track.colour if identity.colour is None else \
            (identity.colour * seen + track.colour * now) / (seen + now)
    if track.walk is not None:
        identity.walk = track.walk
    identity.frames += track.frames
    identity.detections += track.detections
    identity.floor += track.floor
    identity.floor_noise += track.floor_noise
    identity.rejoins.append(rejoin)


def rejoin_tracks(tracks: list[Track], fps: float,
                  within_s: float = REJOIN_WITHIN_S) -> tuple[list[Track], list[Rejoin]]:
    """``tracks`` (a tracker's, each in frame order) -> one track per identity (the first track's id, its
    continuations' frames appended) and every re-join made. ``within_s`` 0: none."""
    identities: list[Track] = []
    rejoins: list[Rejoin] = []
    for track in sorted(tracks, key=lambda t: t.frames[0]):
        continued = likeliest_continued(identities, track, fps, within_s)
        if continued is None:
            identities.append(dataclasses.replace(track, frames=list(track.frames),
                                                  detections=list(track.detections), floor=list(track.floor),
                                                  floor_noise=list(track.floor_noise), rejoins=list(track.rejoins)))
            continue
        join(continued[0], track, continued[1])
        rejoins.append(continued[1])
    return identities, rejoins
