"""One floor for a live run's cameras (issue 66): what every camera's people show of it, pooled.

The cameras of one live run stand in one world frame over one floor, and what a person shows of it is expressed
of the floor itself (``refine.ankle_plane.floor_evidence``), so every camera's lifts draw on every camera's people
(``FloorPool``: bounded, shared by the cameras' ``Finisher`` threads; on Ray, in an actor of its own,
``live.cluster``), on what earlier runs of the site's store showed (``FloorPool.remember``), and on the ankles of
people two cameras saw at once: where the live join decides that two cameras' tracks are one person, their ankle
keypoints' rays are crossed (``JoinedAnkles``, ``refine.ankle_plane.seen_twice``)."""

from __future__ import annotations

import collections
import dataclasses
import threading

import numpy as np

from ray3d import body
from ray3d.refine.ankle_plane import AnklePlane, SeenTwice, seen_twice

EVIDENCE_KEPT = 500  # people (and people seen twice) whose evidence a run keeps: the latest; beyond, no gain
# The joints a crossing reads (``seen_twice``): a track keeps their rays only, to be crossed when it is joined.
CROSSED_JOINTS = (body.PELVIS, *body.ANKLES)
JOINS_WAITING = 64  # joins whose tracks are still being lifted; the oldest beyond are given up
TRACKS_WAITING = 256  # lifted tracks' rays kept for a join not yet decided (a backstop: joins let them go)


class FloorPool:
    """What the people of one live run's cameras have shown of their floor: the latest ``kept`` people's
    ``SizeEvidence`` and ``SeenTwice`` of this run (``add``), and what earlier runs showed (``remember``), as a
    lift's ``LiftOptions.seen_before`` takes it (``evidence``). Safe to share between threads."""

    def __init__(self, kept: int = EVIDENCE_KEPT):
        self._earlier: tuple = ()
        self._people: collections.deque = collections.deque(maxlen=kept)
        self._ankles: collections.deque = collections.deque(maxlen=kept)
        self._lock = threading.Lock()

    def remember(self, evidence) -> None:
        with self._lock:
            self._earlier = tuple(evidence)

    def add(self, evidence) -> None:
        with self._lock:
            for e in evidence:
                (self._ankles if isinstance(e, SeenTwice) else self._people).append(e)

    def evidence(self) -> tuple:
        with self._lock:
            return (*self._earlier, *self._people, *self._ankles)


@dataclasses.dataclass(frozen=True)
class TrackFloor:
    """What one lifted track showed of the floor: its ``evidence`` of the floor itself, the ``keypoints`` layout
    its detector gives (whose planted ankle stands ``contact_m`` over the floor) and, to be crossed with another
    camera's track of the same person, its camera's (3,) ``centre``, frame ids (T,), the (T, 3, 3) directions of
    the rays of ``CROSSED_JOINTS`` and (T, 3) whether each was seen, at ``fps``."""

    evidence: tuple
    keypoints: str
    contact_m: float
    centre: np.ndarray
    frames: np.ndarray
    rays: np.ndarray
    seen: np.ndarray
    fps: float

    def joint_rays(self) -> tuple[np.ndarray, np.ndarray]:
        """(T, 17, 3) ray directions and (T, 17) seen, as ``seen_twice`` reads them (the other joints unseen)."""
        rays = np.full((len(self.frames), 17, 3), np.nan)
        seen = np.zeros((len(self.frames), 17), dtype=bool)
        rays[:, list(CROSSED_JOINTS)], seen[:, list(CROSSED_JOINTS)] = self.rays, self.seen
        return rays, seen


def crossed(first: TrackFloor, second: TrackFloor, first_ticks: np.ndarray, second_ticks: np.ndarray
            ) -> SeenTwice | None:
    """Two cameras' tracks of one person, their frames as ``ticks`` of one clock: where their planted ankles
    stand over the floor itself (the detectors' planted ankles' heights taken off, as ``Lifter`` does), None
    where they share too little or their rays do not meet as one person's."""
    _, rows_a, rows_b = np.intersect1d(first_ticks, second_ticks, return_indices=True)
    if not len(rows_a):
        return None
    (rays_a, seen_a), (rays_b, seen_b) = first.joint_rays(), second.joint_rays()
    found = seen_twice((first.centre, second.centre), (rays_a[rows_a], rays_b[rows_b]),
                       (seen_a[rows_a], seen_b[rows_b]), min(first.fps, second.fps))
    if found is None:
        return None
    return dataclasses.replace(found, height_m=found.height_m - (first.contact_m + second.contact_m) / 2)


class JoinedAnkles:
    """The live join's people seen by two cameras at once, crossed once each camera's track of them is lifted:
    ``lifted`` each track's ``TrackFloor`` as it comes (None: it gave none), ``joined`` each person's tracks as
    the join decides them; both return the ``(SeenTwice, (view, view))`` now found. ``ticks(view, frames)``
    puts a camera's frame ids on one clock (whole ticks). Bounded: a join still waiting when ``JOINS_WAITING``
    newer ones wait is given up."""

    def __init__(self, ticks):
        self.ticks = ticks
        self._tracks: collections.OrderedDict = collections.OrderedDict()
        self._joins: collections.deque = collections.deque(maxlen=JOINS_WAITING)

    def lifted(self, view: int, track: str, floor: TrackFloor | None) -> list:
        self._tracks[view, track] = floor
        while len(self._tracks) > TRACKS_WAITING:
            self._tracks.popitem(last=False)
        return self._cross()

    def joined(self, members: list[tuple[int, str]]) -> list:
        self._joins.append(list(members))  # one camera's alone too: its tracks' rays are let go once they are in
        return self._cross()

    def _cross(self) -> list:
        found, waiting = [], collections.deque(maxlen=JOINS_WAITING)
        for members in self._joins:
            if not all(member in self._tracks for member in members):
                waiting.append(members)
                continue
            floors = {member: self._tracks.pop(member) for member in members}
            for a, b in ((a, b) for a in members for b in members if a[0] < b[0]):
                if floors[a] is not None and floors[b] is not None and (crossing := crossed(
                        floors[a], floors[b], self.ticks(a[0], floors[a].frames),
                        self.ticks(b[0], floors[b].frames))) is not None:
                    found.append((crossing, (a[0], b[0])))
        self._joins = waiting
        return found


def floor_shown(camera: str, plane: AnklePlane) -> dict:
    """A camera's floor as the live page shows it: its line (``AnklePlane.message``) and the same in numbers
    (the people's floor over the camera's z = 0 +/- its sd, the chance the camera file's floor is off, the people
    and the people seen twice it was found from)."""
    observed = None if plane.observed_m is None else round(plane.observed_m - plane.contact_m, 4)
    return {"camera": camera, "line": plane.message(camera), "decision": plane.decision,
            "floor_z_m": round(plane.floor_z_m, 4), "observed_m": observed,
            "observed_sd_m": None if plane.observed_sd_m is None else round(plane.observed_sd_m, 4),
            "chance_off": None if plane.chance_off is None else round(plane.chance_off, 3),
            "people": plane.people, "seen_twice": plane.seen_twice}
