"""Several cameras' people as one, as they arrive: each camera's tracks (``LivePeople``) joined into world
people by the rules of ``ray3d.fusion``, causally.

A camera's new track is held back for its first ``decide_s`` (three updates at least) while it is compared: it
joins the world person whose fused floor point it stayed within the gate of in every update (``pair_distance``'s
gate: 3 combined sds of the two places plus 0.25 m), never one that camera sees as another track now, or a
person all of whose tracks ended within ``handover_s`` where their walk would have taken them
(``handover_reach_m``); otherwise it is a new person. While two world people are about as near (within
0.25 m of each other's distance: people crossing), it waits, ``WAIT_S`` at most; another camera's track not yet
decided is a candidate only where no world person is. A join is never undone. Each world person's joints are
the information-weighted mean of their tracks' latest answers (``Positioned.joint_covariances``: long along each joint's
ray, narrow across it), from the tracks seen within one and a half frame periods (the slowest camera's)."""

from __future__ import annotations

import dataclasses
from collections import deque

import numpy as np

from ray3d.fusion.tracks import GATE_FLOOR_M, gate_m, handover_reach_m
from ray3d.geometry import Camera
from ray3d.geometry.uncertainty import PersonNow, information_weighted, root_spread
from ray3d.temporal import velocity

WALK_S = 0.5  # a velocity is taken over the last half second of places, once they span half of it
AMBIGUOUS = "ambiguous"  # two people as near as each other: wait
WAIT_S = 1.0  # the longest a new track waits for who it is to become clear


class _Path:
    """Recent floor points and their times: where somebody is and how they walk."""

    def __init__(self):
        self.places: deque = deque()

    def add(self, time_s: float, place: np.ndarray) -> None:
        """The place at ``time_s``; a later answer for the same moment (another camera's) replaces it."""
        if self.places and self.places[-1][0] >= time_s:
            self.places.pop()
        self.places.append((time_s, place.copy()))
        while self.places[-1][0] - self.places[0][0] > WALK_S:
            self.places.popleft()

    def velocity(self) -> np.ndarray | None:
        """(2,) m/s, or None while the places span too little time to tell."""
        moved, span = velocity([t for t, _ in self.places], np.stack([p for _, p in self.places]), WALK_S, 0.0)
        return moved[-1] if span[-1] >= WALK_S / 2 else None


@dataclasses.dataclass
class _CameraTrack:
    now: PersonNow
    seen_s: float
    first_s: float
    updates: int = 0
    agreeing: tuple[str | None, int] = (None, 0)  # (world person, updates in a row it stayed within the gate)
    person: str | None = None
    finished: bool = False
    undecided: list = dataclasses.field(default_factory=list)  # (time_s, PersonNow) while who it is was open


@dataclasses.dataclass
class _WorldPerson:
    members: set = dataclasses.field(default_factory=set)  # (view, track)
    path: _Path = dataclasses.field(default_factory=_Path)  # their fused floor points
    seen_s: float = -np.inf


class LiveFusion:
    """``update(view, time_s, people)`` -> the world's people now (their ``track`` the world person's id);
    ``finished(view, track)`` when a camera's tracker lets a track go; ``ended(time_s)`` -> the world people
    gone for good (every track finished, and ``handover_s`` passed). ``joined`` holds who each of those was,
    [(person, [(view, track), ...])], until the caller takes it: the world file is fused by the same join
    (``fusion.fuse_worlds``'s ``groups``). ``decided`` holds, until the caller takes it, what a track saw while
    who it was stayed open ([(time_s, PersonNow)], named by the person it then joined or became), so that a
    caller holding its frames ``WAIT_S`` and a little longer misses nobody's first moments."""

    def __init__(self, cameras: list[Camera], frame_period_s: float, handover_s: float = 2.0, decide_s: float = 0.1,
                 id_prefix: str = ""):
        self.id_prefix = id_prefix  # before each world person's number (a run's: unique across a store's runs)
        self.centres = [camera.center for camera in cameras]
        self.handover_s, self.decide_updates = handover_s, max(3, int(round(decide_s / frame_period_s)))
        self.recent_s = 1.5 * frame_period_s  # seen now: every camera's latest frame, whatever their phases
        self._tracks: dict[tuple[int, str], _CameraTrack] = {}
        self._people: dict[str, _WorldPerson] = {}  # the world people not gone for good
        self._next_person = 0
        self.joined: list[tuple[str, list[tuple[int, str]]]] = []
        self.decided: list[tuple[float, PersonNow]] = []

    def update(self, view: int, time_s: float, people: list[PersonNow]) -> list[PersonNow]:
        for now in people:
            key = (view, now.track)
            track = self._tracks.setdefault(key, _CameraTrack(now, time_s, time_s))
            track.now, track.seen_s = now, time_s
            track.updates += 1
            if track.person is None:
                track.undecided.append((time_s, now))
                self._decide(key, track, time_s)
        return [p for n, person in self._people.items() if (p := self._fused(n, person, time_s)) is not None]

    def finished(self, view: int, track: str) -> None:
        if (view, track) in self._tracks:
            self._tracks[view, track].finished = True
            if self._tracks[view, track].person is None:  # never long enough to be anybody
                del self._tracks[view, track]

    def ended(self, time_s: float, seen: bool = False) -> list:
        """The world people gone for good at ``time_s`` (with ``seen``: with when they were last seen)."""
        gone = [(n, person.seen_s) for n, person in self._people.items()
                if all(self._tracks[k].finished for k in person.members) and time_s - person.seen_s > self.handover_s]
        for n, _ in gone:  # forgotten: a long stream keeps only who may still be in view
            members = self._people.pop(n).members
            self.joined.append((n, sorted(members)))
            for key in members:
                self._tracks.pop(key, None)
        return gone if seen else [n for n, _ in gone]

    def _decide(self, key: tuple[int, str], track: _CameraTrack, time_s: float) -> None:
        """Join the track to the world person (or the other camera's undecided track, making one new person
        of both) it has agreed with for ``decide_updates`` updates running; a new person when it agrees with
        nobody then. While two are as near (people crossing) it waits, ``WAIT_S`` at most."""
        candidate, other = self._nearest(key, track, time_s), None
        held, count = track.agreeing
        track.agreeing = (candidate, count + 1 if candidate not in (None, AMBIGUOUS) and candidate == held else 0)
        if candidate not in (None, AMBIGUOUS) and track.agreeing[1] >= self.decide_updates:
            other = self._tracks[candidate] if isinstance(candidate, tuple) else None
            track.person = candidate if other is None else other.person
            if track.person is None:  # the other camera's track is undecided too
                track.person = other.person = self._new_person()
                self._people[track.person].members.add(candidate)
        elif (candidate is None and track.updates >= self.decide_updates) or time_s - track.first_s >= WAIT_S:
            track.person = self._new_person()
        if track.person is not None:
            self._people[track.person].members.add(key)
            for joined in (track, other) if other is not None else (track,):
                self.decided += [(at, dataclasses.replace(now, track=track.person, tracked=None, clothes=None))
                                 for at, now in joined.undecided]
                joined.undecided = []

    def _new_person(self) -> str:
        person, self._next_person = f"{self.id_prefix}{self._next_person}", self._next_person + 1
        self._people[person] = _WorldPerson()
        return person

    def _nearest(self, key: tuple[int, str], track: _CameraTrack, time_s: float):
        """The world person (their id), or another camera's undecided track (its key), that this track's
        latest place agrees with best, if any may be them."""
        place, sd = track.now.joints[0, :2], float(np.max(track.now.position_sd))
        options = []  # (how far off, what)
        for n, person in self._people.items():
            if not person.path.places or any(
                    k[0] == key[0] and time_s - self._tracks[k].seen_s <= self.recent_s for k in person.members):
                continue  # this camera sees them as another track now
            gap_s = time_s - person.seen_s
            last_s, last_place = person.path.places[-1]
            if gap_s <= self.recent_s:  # seen now by another camera: within the gate
                spread = max(float(np.max(self._tracks[k].now.position_sd)) for k in person.members
                             if time_s - self._tracks[k].seen_s <= self.recent_s)
                options.append((float(np.linalg.norm(place - last_place)), gate_m(sd, spread), n))
            elif gap_s <= self.handover_s:  # gone from every camera lately: where their walk leads
                velocity = person.path.velocity()
                walked = last_place + (0.0 if velocity is None else velocity) * (time_s - last_s)
                options.append((float(np.linalg.norm(place - walked)), handover_reach_m(gap_s), n))
        for other_key, other in self._tracks.items():
            if other_key[0] != key[0] and other.person is None and time_s - other.seen_s <= self.recent_s:
                options.append((float(np.linalg.norm(place - other.now.joints[0, :2])),
                                gate_m(sd, float(np.max(other.now.position_sd))), other_key))
        # World people first; another camera's undecided track only where no world person may be them.
        people = sorted((miss, what) for miss, allowed, what in options if miss <= allowed and isinstance(what, str))
        if len(people) > 1 and people[1][0] - people[0][0] < GATE_FLOOR_M:
            return AMBIGUOUS
        tracks = sorted((miss, what) for miss, allowed, what in options if miss <= allowed and isinstance(what, tuple))
        return people[0][1] if people else tracks[0][1] if tracks else None

    def _fused(self, n: str, person: _WorldPerson, time_s: float) -> PersonNow | None:
        """The person's joints from their tracks seen now (None when none was)."""
        current = [(view, self._tracks[view, track]) for view, track in sorted(person.members)
                   if time_s - self._tracks[view, track].seen_s <= self.recent_s]
        if not current:
            return None
        joints, covariance = information_weighted(
            np.stack([t.now.joints for _, t in current]),
            np.stack([t.now.joint_covariances(self.centres[view]) for view, t in current]))
        person.seen_s = max(t.seen_s for _, t in current)
        person.path.add(person.seen_s, joints[0, :2])  # when the newest of its answers was seen
        statures = [t.now.stature_m for _, t in current if t.now.stature_m is not None]
        return PersonNow(n, joints, root_spread(covariance[None])[0], float(np.mean(statures)) if statures else None)
