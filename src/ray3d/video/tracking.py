"""Who is who: detections linked into tracks on the floor plan, in metres.

Each person is a constant-velocity Kalman filter (OpenCV's ``cv2.KalmanFilter``) on the floor point between
their ankles (the camera says where that pixel's ray meets the floor); detections are assigned to people by
the Hungarian method (scipy's ``linear_sum_assignment``) on the Mahalanobis distance of that point plus the
colour of their clothes, so that two people crossing in the image, at different depths or in different
clothes, keep their ids. One box for two people walking side by side or passing each other (the detector merged
them for a few frames) is given to neither: they coast until they part. A person unseen for longer than
``max_gap_s`` has left: their track ends, and whoever appears later starts a new one (a track never bridges a long
gap, so it never joins two people) unless ``rejoin_s`` is given: live, where no later pass over the whole tracks
can, a person let go is kept that long for a track confirmed after it to continue (``video.identities``: where
their walk led, in their clothes), and only then handed over as ``finished``.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment

from ray3d.geometry import Camera
from ray3d.video.boxes import box_inside, box_overlap
from ray3d.video.clothes import COLOUR_GATE, colour_distance
from ray3d.video.detectors import Detection
from ray3d.video.floor_points import FloorPoint, FloorPoints
from ray3d.video.identities import join, likeliest_continued
from ray3d.video.track import Track

_GATE = 13.8  # chi-square, 2 degrees of freedom, 99.9 %: beyond it a detection cannot be that person
_APPEARANCE_WEIGHT = 15.0  # cost of entirely different clothes, in squared standard deviations of position
# A detection whose image box overlaps this much (intersection over union) the box of a person seen in the last
# frame is still them when their floor point jumps beyond the gate: a near person lifting or swinging a leg moves
# the point between their ankles by more than a stride. (Not for a person missed: at a crossing the one in front
# would take the place of the one hidden.)
_SAME_BOX = 0.5
CONFIRM_FRAMES = 3  # detections in a row before a person counts (one-off false detections never do)
# Frames given in a row a followed person may be missed in and keep their track, however far apart the frames given.
MISSES_KEPT = 2
# A person in view when a run was cut off is taken up by a track confirmed in the next run's first CLAIM_S
# seconds within CLAIM_GATE_M, plus a brisk walk since, of where their walk led from their last place or of that
# place itself (a young track's walk may be far off; who stopped or turned is within it), in clothes of their colours.
CLAIM_S = 3.0
CLAIM_GATE_M = 0.8
CLAIM_SPEED_M_S = 2.0
# How far a walk read before a cut still tells the walk after it (m/s, sd): a walker changes pace and heading by
# about this much over the second or two a restart takes.
CARRIED_WALK_SD_M_S = 0.5
TOGETHER_M = 3.0  # two people one box may hold: side by side, or one passing a few metres behind the other
# How much of each one's last box lies inside a box that holds both: a box merged as two people pass is a compromise
# that may leave more than half of the narrower one outside (vtest.avi, frame 768: 46 %).
HELD_INSIDE = 0.4


class _Person:
    """A tracked person's filter (state x, y, vx, vy in metres and m/s) and clothes colour."""

    def __init__(self, floor: np.ndarray, noise: np.ndarray, colour: np.ndarray, dt: float, acceleration: float):
        self.filter = cv2.KalmanFilter(4, 2, 0, cv2.CV_64F)
        self.filter.transitionMatrix = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1]], np.float64)
        self.filter.measurementMatrix = np.eye(2, 4, dtype=np.float64)
        # White acceleration noise, integrated over one frame.
        q = np.array([[dt ** 4 / 4, dt ** 3 / 2], [dt ** 3 / 2, dt ** 2]]) * acceleration ** 2
        self.filter.processNoiseCov = np.kron(q, np.eye(2))  # states ordered x, y, vx, vy
        self.filter.statePost = np.array([[floor[0]], [floor[1]], [0.0], [0.0]])
        self.filter.errorCovPost = np.diag([noise[0, 0], noise[1, 1], 2.0 ** 2, 2.0 ** 2]).astype(np.float64)
        self.colour, self.hits, self.missed = colour, 1, 0
        self.box: np.ndarray | None = None  # (4,) the image box of their last detection
        self.together = False  # one detection held both them and somebody beside or passing them (``_held_together``)
        self.track: Track | None = None
        self.waiting: list[tuple] = []  # (frame, detection, floor point, its covariance) until confirmed

    def predict(self, frames: int = 1) -> None:
        """The state ``frames`` frames on from the last (more than one where frames were skipped or dropped)."""
        self.filter.predict()
        for _ in range(frames - 1):
            self.filter.statePost = self.filter.statePre.copy()
            self.filter.errorCovPost = self.filter.errorCovPre.copy()
            self.filter.predict()

    def distance(self, floor: np.ndarray, noise: np.ndarray) -> float:
        """Squared Mahalanobis distance of a measured floor point from the prediction."""
        innovation = floor - self.filter.statePre[:2, 0]
        covariance = self.filter.errorCovPre[:2, :2] + noise
        return float(innovation @ np.linalg.solve(covariance, innovation))

    def correct(self, floor: np.ndarray, noise: np.ndarray) -> None:
        self.filter.measurementNoiseCov = noise
        self.filter.correct(floor.reshape(2, 1).astype(np.float64))
        self.hits, self.missed = self.hits + 1, 0

    def learn_colour(self, colour: np.ndarray) -> None:
        """Their clothes seen again where nobody else's can be mixed in."""
        self.colour = 0.8 * self.colour + 0.2 * colour

    def walk_on(self, walk: np.ndarray) -> None:
        """Their walk as read before a cut (vx, vy m/s), known to ``CARRIED_WALK_SD_M_S``, weighed with the one the
        filter read from its own few frames since (a Kalman update of the velocity alone)."""
        velocity = np.eye(2, 4, 2)  # the state's vx, vy
        covariance = self.filter.errorCovPost
        gain = covariance @ velocity.T @ np.linalg.inv(velocity @ covariance @ velocity.T
                                                       + CARRIED_WALK_SD_M_S ** 2 * np.eye(2))
        self.filter.statePost = self.filter.statePost + gain @ (np.asarray(walk, np.float64).reshape(2, 1)
                                                                 - velocity @ self.filter.statePost)
        self.filter.errorCovPost = (np.eye(4) - gain @ velocity) @ covariance

    def coast(self, frames: int = 1) -> None:
        """No detection for ``frames`` frames: the prediction stands."""
        self.filter.statePost = self.filter.statePre.copy()
        self.filter.errorCovPost = self.filter.errorCovPre.copy()
        self.missed += frames


class _CarriedIds:
    """The people in view when an earlier run on this stream was cut off (``site.events.CarriedPerson``: id, last
    place and its stream time, walk and clothes), for tracks confirmed in the stream's first ``CLAIM_S`` seconds to
    take up."""

    def __init__(self, carried, dt: float):
        # Each one's last place as a tracker measures it: where theirs put them, else their lifted place.
        self._carried = [person for person in carried if person.tracked is not None or person.place is not None]
        self.dt = dt
        self._claim_until: int | None = None  # the last frame in which a carried person's id may be taken up

    def start(self, frame_index: int) -> None:
        """A frame of the stream: the first one given opens the time in which ids may be taken up."""
        if self._claim_until is None:
            self._claim_until = frame_index + int(round(CLAIM_S / self.dt))

    def claim(self, person: _Person, seen: list[_Person], frame_index: int) -> str | None:
        """The id of the carried person (``CarriedPerson``) ``person`` is, just confirmed, if it is still early
        enough; taken, and their walk given to its filter. Of everybody ``seen`` in this frame and not followed yet
        (each where they were found, with that point's covariance, and the colours of their clothes), the likeliest
        assignment to the carried people decides (the Hungarian method on each pair's ``_unlikeness``; anybody may
        be somebody new). None: nobody (or somebody seen too late)."""
        if not self._carried or frame_index > self._claim_until:
            return None
        seen = [person] + [other for other in seen if other.track is None and other is not person]
        somebody_new = 1.0 + COLOUR_GATE  # costlier than any pair within the gates: one within them is taken
        cost = np.full((len(seen), len(self._carried) + len(seen)), np.inf)
        for r, other in enumerate(seen):
            cost[r, :len(self._carried)] = [_unlikeness(carried, other.filter.statePost[:2, 0], other.waiting[-1][3],
                                                        other.colour, frame_index * self.dt)
                                            for carried in self._carried]
            cost[r, len(self._carried) + r] = somebody_new
        rows, columns = linear_sum_assignment(np.where(np.isfinite(cost), cost, 1e6))
        taken = int(columns[list(rows).index(0)])
        if taken >= len(self._carried):
            return None
        carried = self._carried.pop(taken)
        if carried.walk:
            person.walk_on(carried.walk)
        return carried.person


def _unlikeness(person, here: np.ndarray, noise: np.ndarray, colour: np.ndarray, now_s: float) -> float:
    """How unlikely a carried person (``CarriedPerson``) is the one found ``here`` (x, y metres; ``noise`` its (2, 2)
    covariance) in clothes of ``colour`` at stream time ``now_s``: how far from where their walk led since they were
    last placed, or from that place (whichever is nearer), in reaches (within ``CLAIM_GATE_M`` and
    ``CLAIM_SPEED_M_S`` since, and two sd of where the floor point may lie: metres along the ray for somebody far
    away), plus how unlike their clothes; infinite beyond either gate."""
    x, y, placed_s = person.tracked if person.tracked else (*person.place, person.place_s)
    since = max(0.0, now_s - placed_s)
    left = np.array([x, y])
    reach = CLAIM_GATE_M + CLAIM_SPEED_M_S * since
    # How many reaches away, the floor point's doubt added: d' (r^2 I + 4 noise)^-1 d, within at 1.
    spread = reach ** 2 * np.eye(2) + 4.0 * noise
    places = [left] + ([left + np.asarray(person.walk) * since] if person.walk else [])
    apart = min(float((here - at) @ np.linalg.solve(spread, here - at)) for at in places)
    unlike = 0.5 if person.clothes is None else colour_distance(np.asarray(person.clothes), colour)
    return np.sqrt(apart) + unlike if apart <= 1.0 and unlike < COLOUR_GATE else np.inf


class FloorTracker:
    """``tracker.update(frame_index, detections, frame)`` once per frame, then ``tracker.tracks()``.

    Args:
        camera: the video's camera.
        fps: the video's frame rate.
        layout: the detections' joint layout.
        max_gap_s: the longest time a person may go undetected and keep their track.
        confirm_hits: detections before a new track counts (one-off false detections never become tracks).
        acceleration: how hard people change speed, m/s^2 (standard deviation).
        id_prefix: written before each track's number (a stream taken up again keeps apart from its old ids).
        carried: people in view when an earlier run on this stream was cut off (``site.events.CarriedPerson``:
            id, last place and its stream time, walk, clothes): a track confirmed within ``CLAIM_S`` of the first
            frame where one of them could have walked to, in clothes like theirs, takes up their id and their walk
            (the likeliest assignment of everybody not followed yet to them), the others are numbered as usual.
        rejoin_s: how long a person let go may be taken up again by a track confirmed after them (the re-join
            rule of ``video.identities``); 0: never (offline, where the whole tracks are re-joined after).
    """

    def __init__(self, camera: Camera, fps: float, layout: str, max_gap_s: float = 0.5,
                 confirm_hits: int = CONFIRM_FRAMES,
                 acceleration: float = 2.0, id_prefix: str = "", carried=(), rejoin_s: float = 0.0):
        self.confirm_hits, self.acceleration, self.rejoin_s = confirm_hits, acceleration, rejoin_s
        self.floor_points = FloorPoints(camera, layout)
        self.dt, self.max_gap = 1.0 / fps, max(1, int(np.floor(max_gap_s * fps)))
        # Every how many frames it is given (a live camera under load takes every k-th): a person may be missed in
        # MISSES_KEPT frames given in a row whatever time that spans, as at the full rate.
        self.frames_apart = 1
        self._active: list[_Person] = []
        self._tracks: list[Track] = []
        self._confirmed = 0  # tracks confirmed so far (their ids), including those handed over by ``finished``
        self.id_prefix = id_prefix
        self._carried = _CarriedIds(carried, self.dt)
        self._last_frame: int | None = None
        self.frames_with_people = 0  # frames in which the detector found anybody

    def update(self, frame_index: int, detections: list[Detection], frame: np.ndarray) -> None:
        """Assign this frame's detections to people (``tracks()`` holds the result). Frames may be skipped
        (live use drops some): people move, and go unseen, for the frames since the last update."""
        elapsed = 1 if self._last_frame is None else max(1, frame_index - self._last_frame)
        self._carried.start(frame_index)
        self._last_frame = frame_index
        self.frames_with_people += bool(detections)
        measured = self.floor_points(detections, frame)
        usable = [i for i, m in enumerate(measured) if m is not None]
        for person in self._active:
            person.predict(elapsed)
        matched_detections = _held_together(self._active, detections, measured, usable)
        matched_people = _matched(self._active, detections, measured,
                                  [i for i in usable if i not in matched_detections])
        matched_detections |= set(matched_people.values())
        for r, i in matched_people.items():
            floor, noise, colour, alone = measured[i]
            # A box overlapping another one, or where somebody not seen now was last seen (they may be behind it),
            # may hold their colours too.
            hiding = any(_overlap(other.box, detections[i].box) > 0.05 for k, other in enumerate(self._active)
                         if k not in matched_people and other.box is not None)
            if alone and not hiding:
                self._active[r].learn_colour(colour)
            self._record(self._active[r], frame_index, detections[i], floor, noise)
        for r, person in enumerate(self._active):
            if r not in matched_people:
                person.coast(elapsed)
        survivors = []
        for person in self._active:
            confirmed = person.track is not None
            if person.missed <= (max(self.max_gap, MISSES_KEPT * self.frames_apart) if confirmed else 0):
                survivors.append(person)
        for i in usable:
            if i not in matched_detections:
                floor, noise, colour, _ = measured[i]
                person = _Person(floor, noise, colour, self.dt, self.acceleration)
                survivors.append(person)
                self._record(person, frame_index, detections[i], floor, noise)
        # Confirmed once everybody seen in this frame is known: a carried person's id goes to the likeliest of them.
        for person in survivors:
            if person.track is None and person.hits >= self.confirm_hits:
                self._confirm(person, survivors, frame_index)
        self._active = survivors

    def tracks(self) -> list[Track]:
        """Every confirmed track so far (less those ``finished`` handed over), in the order they were confirmed."""
        return list(self._tracks)

    def finished(self) -> list[Track]:
        """The tracks whose person has left (unseen for longer than ``max_gap_s``, and not taken up again within
        ``rejoin_s``), handed over and forgotten: live use keeps only the people in view."""
        kept = [self._kept(track) for track in self._tracks]
        done = [track for track, keep in zip(self._tracks, kept) if not keep]
        self._tracks = [track for track, keep in zip(self._tracks, kept) if keep]
        return done

    def _kept(self, track: Track) -> bool:
        """Whether a track is still followed, or may still be taken up by a track confirmed later (one that
        starts within ``rejoin_s`` of its last frame: begun already, or yet to begin)."""
        if any(person.track is track for person in self._active):
            return True
        horizon = track.frames[-1] + self.rejoin_s / self.dt
        return self.rejoin_s > 0 and (self._last_frame <= horizon or any(
            person.track is None and person.waiting[0][0] <= horizon for person in self._active))

    def _record(self, person: _Person, frame_index: int, detection: Detection, floor: np.ndarray,
                noise: np.ndarray) -> None:
        person.box = detection.box
        if person.track is not None:
            person.track.frames.append(frame_index)
            person.track.detections.append(detection)
            person.track.floor.append(floor)
            person.track.floor_noise.append(noise)
            person.track.colour, person.track.walk = person.colour, person.filter.statePost[2:, 0].copy()
            return
        person.waiting.append((frame_index, detection, floor, noise))

    def _confirm(self, person: _Person, seen: list[_Person], frame_index: int) -> None:
        """A person detected ``confirm_hits`` times becomes a track: a carried person's (of everybody ``seen`` in
        this frame), or one let go taken up again, or somebody new."""
        frames, detections, floor, noise = (list(column) for column in zip(*person.waiting))
        track_id = self._carried.claim(person, seen, frame_index)
        carried = track_id is not None
        if not carried:
            track_id = f"{self.id_prefix}{self._confirmed}"
            self._confirmed += 1
        person.track = Track(track_id, frames, detections, floor, person.colour, noise,
                             walk=person.filter.statePost[2:, 0].copy(), carried=carried)
        continued = None if carried or not self.rejoin_s else likeliest_continued(
            [track for track in self._tracks if not any(p.track is track for p in self._active)], person.track,
            1 / self.dt, self.rejoin_s)
        if continued is None:
            self._tracks.append(person.track)
        else:  # somebody let go, taken up again: their track goes on
            identity, rejoin = continued
            join(identity, person.track, rejoin)
            person.track = identity


def _matched(people: list[_Person], detections: list[Detection], measured: list[FloorPoint | None],
             free: list[int]) -> dict[int, int]:
    """People (their rows in ``people``) -> the detection each is given, of the ``free`` ones, their filters
    corrected by it. A matching cascade: people seen in the last frame choose first, then those missed for one
    frame, and so on, tentative tracks last; a person coasting behind somebody cannot take the detection of the
    person in front, who is still being seen."""
    def priority(person: _Person) -> tuple[bool, int]:
        return person.track is None, person.missed

    matched: dict[int, int] = {}
    for level in sorted({priority(p) for p in people}):
        rows = [r for r, p in enumerate(people) if priority(p) == level]
        cols = [i for i in free if i not in matched.values()]
        if not cols:
            break
        cost = _assignment_cost([people[r] for r in rows], [detections[i] for i in cols], [measured[i] for i in cols])
        chosen_rows, chosen_cols = linear_sum_assignment(np.where(np.isfinite(cost), cost, 1e6))
        for a, b in zip(chosen_rows, chosen_cols):
            if np.isfinite(cost[a, b]):
                r, i = rows[a], cols[b]
                matched[r] = i
                people[r].correct(*measured[i][:2])
    return matched


def _assignment_cost(people: list[_Person], detections: list[Detection], measured: list[FloorPoint]) -> np.ndarray:
    """(people, detections) the cost of giving each detection to each person: the squared Mahalanobis distance of
    its floor point plus how unlike their clothes are; infinite where it cannot be them (beyond the gate in
    position, unless it is the box they had in the last frame, or in clothes)."""
    cost = np.full((len(people), len(detections)), np.inf)
    for a, person in enumerate(people):
        for b, (detection, point) in enumerate(zip(detections, measured)):
            d2 = person.distance(point.floor, point.noise)
            unlike = colour_distance(person.colour, point.colour)
            if unlike >= COLOUR_GATE:
                continue
            if d2 < _GATE:
                cost[a, b] = d2 + _APPEARANCE_WEIGHT * unlike
            elif person.missed == 0 and _overlap(person.box, detection.box) >= _SAME_BOX:
                cost[a, b] = _GATE + _APPEARANCE_WEIGHT * unlike
    return cost


def _held_together(people: list[_Person], detections: list[Detection], measured: list[FloorPoint | None],
                   usable: list[int]) -> set[int]:
    """The detections that hold two people walking together or passing each other: each near two followed
    people who were seen in the last frame (or held together since) within ``TOGETHER_M`` of each other, its
    box covering most of both their last boxes and more than either (not one person in front of another
    hidden), and no other detection near either. Given to neither (they coast until they part, or for
    ``max_gap_s``): whichever took it would carry on as the other when they do. Marks the people it holds
    ``together``."""
    seen = [p for p in people if p.track is not None and (p.missed == 0 or p.together)]
    for person in people:
        person.together = False
    held = set()
    for a, first in enumerate(seen):
        for second in seen[a + 1:]:
            if np.linalg.norm(first.filter.statePre[:2, 0] - second.filter.statePre[:2, 0]) > TOGETHER_M:
                continue
            near = [i for i in usable if first.distance(*measured[i][:2]) < _GATE
                    or second.distance(*measured[i][:2]) < _GATE]
            # Their last boxes (before the first such frame) both largely inside it; held since, while it lasts.
            if len(near) != 1:
                continue
            box = detections[near[0]].box
            if all(p.missed or (box_inside(p.box, box) >= HELD_INSIDE and box_inside(box, p.box) < 0.8)
                   for p in (first, second)):
                held.add(near[0])
                first.together = second.together = True
    return held


def _overlap(a: np.ndarray, b: np.ndarray) -> float:
    return float(box_overlap(a[None], b[None])[0, 0])
