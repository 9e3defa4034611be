"""A site's events, on both clocks from one engine: ``SiteMonitor`` follows each person causally, frame by frame
(what ``ray3d live`` runs as frames arrive), and ``site_events`` replays a finished world through it (what
``ray3d site`` and ``ray3d video --site`` report), so the live and offline events are equal by construction.

Every kind of event is one row of ``EVENT_KINDS`` (its name, its colour in the report and the fields it carries
beside ``event``, ``track`` and ``time_s``) and one method of ``SiteMonitor`` that finds it. An event is an
``Event``: a dict, written as one JSON line as it is.

The rules: a line crossed (``line_crossings`` on the step just taken); a zone entered or left (``in_zones``: a
person is in a zone while their latest place lies in it; a visit under way when a track starts is no entry, one
under way when it ends no exit); a zone's occupancy above its limit (counted from who is in it, those there when
their track started too, when an entry makes it too many); a visit's dwell above its limit (when it reaches it); a
fall (``falls`` on the person's last seconds, once they have lain still long enough for it to count); a track
started and ended. A track's time in a zone is the dwell of its visits, the one under way at its end too
(``SiteMonitor.time_in_zones``, ``SiteReplay.time_in_zones``).
"""

from __future__ import annotations

import dataclasses
from collections import deque

import numpy as np

from ray3d.io.world import World
from ray3d.site.falls import FALL_STILL_S, FALL_WINDOW_S, falls
from ray3d.site.places import Site, in_zones, line_crossings


@dataclasses.dataclass(frozen=True)
class EventKind:
    """A kind of event: its ``name`` (the ``event`` field), its ``colour`` in reports and the ``fields`` it carries
    beside ``event``, ``track`` and ``time_s``."""

    name: str
    colour: str
    fields: tuple[str, ...]
    optional: tuple[str, ...] = ()  # fields it may carry too


LINE_CROSSED = EventKind("line crossed", "#d62f2f", ("line", "direction", "place_m", "sides_m", "frames"))
ZONE_ENTERED = EventKind("zone entered", "#1f77b4", ("zone", "place_m", "frames"))
# A run cut off (killed outright) leaves its visits and tracks open; the next run on its store ends them with a
# ``reason`` (``store.restart``).
ZONE_LEFT = EventKind("zone left", "#7fb2e5", ("zone", "place_m", "dwell_s", "frames"), ("reason",))
OCCUPANCY_ABOVE_LIMIT = EventKind("occupancy above limit", "#ff7f0e", ("zone", "occupancy", "limit", "people"))
DWELL_ABOVE_LIMIT = EventKind("dwell above limit", "#9467bd", ("zone", "dwell_s", "limit_s"))
FALL = EventKind("fall", "#000000", ("place_m", "head_drop_m", "drop_s", "lying_from_s", "still_m"))
TRACK_STARTED = EventKind("track started", "#2ca02c", ("place_m", "frames"))
TRACK_ENDED = EventKind("track ended", "#98df8a", ("place_m", "frames"), ("reason",))
EVENT_KINDS = {kind.name: kind for kind in (LINE_CROSSED, ZONE_ENTERED, ZONE_LEFT, FALL, OCCUPANCY_ABOVE_LIMIT,
                                             DWELL_ABOVE_LIMIT, TRACK_STARTED, TRACK_ENDED)}


class Event(dict):
    """One event: ``{"event": kind name, "track", "time_s", **the kind's fields}``; refused (``ValueError``) when
    the fields are not its kind's (its optional ones may be there too)."""

    def __init__(self, kind: EventKind, track: str, time_s: float, **fields):
        if not set(kind.fields) <= set(fields) <= {*kind.fields, *kind.optional}:
            raise ValueError(f"a {kind.name!r} event carries {', '.join(kind.fields)}; got {', '.join(fields)}")
        super().__init__(event=kind.name, track=str(track), time_s=float(time_s),
                         **{name: fields[name] for name in (*kind.fields, *kind.optional) if name in fields})

    def __reduce__(self):  # sent between processes (a webhook thread, Ray) as what it is
        return _event_from_dict, (dict(self),)


SERVICE_STOPPED = "the service stopped"  # the reason of the events that close what a run cut off left open


@dataclasses.dataclass(frozen=True)
class CarriedPerson:
    """A person in view when a run was cut off (killed outright), whose track the next run on the store may take
    up (``store.restart``): their id ``person``, their last ``place`` (x, y) on the floor, or None, at ``place_s``,
    and the run's last moment ``last_s`` (both on the stream clock, which a file taken up keeps), the zones they
    were in, each with the stream time its visit began (``visits``), the stream time they last crossed each
    line (``crossed``), and where their camera's tracker last placed them (``tracked``: x, y and its stream time;
    None where unknown), in the terms the next run's tracker finds people in (``place`` is the lifted pelvis, the
    site's), with the walk it read there (``walk``: vx, vy m/s) and their clothes' colours (``clothes``, the
    tracker's histogram), each None where unknown."""

    person: str
    place: tuple[float, float] | None
    place_s: float
    last_s: float
    visits: dict = dataclasses.field(default_factory=dict)
    crossed: dict = dataclasses.field(default_factory=dict)
    tracked: tuple[float, float, float] | None = None
    walk: tuple[float, float] | None = None
    clothes: tuple[float, ...] | None = None

    def closing(self) -> list[Event]:
        """What ends them when no run takes them up: each visit's "zone left", then "track ended", at ``last_s``
        with ``reason`` "the service stopped" (no frame saw these ends: ``frames`` is empty)."""
        place = None if self.place is None else [round(float(v), 3) for v in self.place]
        return [*(Event(ZONE_LEFT, self.person, round(self.last_s, 3), zone=zone, place_m=place,
                        dwell_s=round(self.last_s - entered, 3), frames=[], reason=SERVICE_STOPPED)
                  for zone, entered in self.visits.items()),
                Event(TRACK_ENDED, self.person, round(self.last_s, 3), place_m=place, frames=[],
                      reason=SERVICE_STOPPED)]


def _event_from_dict(document: dict) -> Event:
    fields = {k: v for k, v in document.items() if k not in ("event", "track", "time_s")}
    return Event(EVENT_KINDS[document["event"]], document["track"], document["time_s"], **fields)


def _place(point: np.ndarray) -> list:
    return np.asarray(point).round(3).tolist()


FALL_CHECK_S = 0.5  # how often each person's last seconds are searched for a fall


class _Person:
    def __init__(self, frames: int):
        self.frame = -1
        self.place: np.ndarray | None = None
        self.inside: dict[str, float] = {}   # zone -> when this visit began (its entry time)
        self.spent: dict[str, float] = {}    # zone -> the dwell of the visits that left it
        self.recent: deque = deque(maxlen=frames)  # (time, joints) over the longest a fall takes to show
        self.falls_reported_until = -np.inf
        self.dwell_reported: set[str] = set()
        self.next_fall_check = 0.0
        self.counted_lines: set[str] = set()  # taken up: lines crossed since their last place, counted already
        self.unannounced: Event | None = None  # their "track started", until they have been followed long enough

    def overstays(self, track: str, zones, now: float) -> list[Event]:
        """Their visits under way past a zone's ``max_dwell_s`` at stream time ``now``, each said once a visit."""
        events = []
        for zone in zones:
            entered = self.inside.get(zone.name)
            if zone.max_dwell_s is None or entered is None or zone.name in self.dwell_reported:
                continue
            if now - entered > zone.max_dwell_s:
                self.dwell_reported.add(zone.name)
                events.append(Event(DWELL_ABOVE_LIMIT, track, round(entered + zone.max_dwell_s, 3), zone=zone.name,
                                    dwell_s=round(now - entered, 3), limit_s=zone.max_dwell_s))
        return events

    def unsaid_falls(self, track: str) -> list[Event]:
        """The falls in their recent frames not said yet."""
        if len(self.recent) < 2:
            return []
        times = np.array([t for t, _ in self.recent])
        found = [fall for fall in falls(times, np.stack([j for _, j in self.recent]))
                 if fall["time_s"] > self.falls_reported_until]
        if found:
            self.falls_reported_until = max(fall["lying_from_s"] + FALL_STILL_S for fall in found)
        return [Event(FALL, track, **fall) for fall in found]


class SiteMonitor:
    """``update(frame index, {track: world joints (17, 3)})`` -> the events of that frame; ``ended(track)`` -> a
    track's last events; ``counts`` holds the entries / exits per zone and the crossings per line and direction so
    far, ``occupants`` who is in each zone now, ``time_in_zones(track)`` how long a track has spent in each. Track
    ids are strings.

    ``carried``: the people a run cut off left in view (``CarriedPerson``), whose tracks this one may take up: one
    seen again goes on from where they were (no "track started"; their visits under way, no entry; a line crossed
    since, counted); ``give_up()`` ends those not seen again.

    ``announced_after_s``: a track's "track started" (dated at its first frame here) is handed over once it has
    been here this long (first to latest frame), or with its first other event, whichever comes first; a track
    that ends before either says nothing, and is nobody in a zone (``occupants``) meanwhile; 0: at once (a finished
    world's tracks are whole). Live passes the job's shortest track, so that a box on part of a person or on two
    people, followed for a moment, is not a person started and ended (the world file and offline events leave such
    tracks out altogether). A live person comes here from the frame that confirms their track (``CONFIRM_FRAMES``
    after it began) to one frame after their last detection, so a track that lasted just over the shortest kept
    (``Track.too_short``), 0.1 s more at 10 frames/s, may end unannounced (with no event either) though the world
    file keeps it."""

    def __init__(self, site: Site, fps: float, carried=(), announced_after_s: float = 0.0):
        self.site, self.fps, self.announced_after_s = site, fps, announced_after_s
        self._people: dict[str, _Person] = {}
        self._carried: dict[str, CarriedPerson] = {person.person: person for person in carried}
        self.counts = {**{zone.name: {"entered": 0, "left": 0} for zone in site.zones},
                       **{line.name: {"forward": 0, "back": 0} for line in site.lines}}

    def update(self, frame_index: int, people: dict[str, np.ndarray]) -> list[Event]:
        now, events = frame_index / self.fps, []
        for track, joints in people.items():
            place = joints[0, :2]
            state = self._people.get(track)
            if state is None and track in self._carried:
                state = self._people[track] = self._taken_up(self._carried.pop(track), place)
            found = []
            if state is None:
                state = self._people[track] = _Person(int(round(FALL_WINDOW_S * self.fps)))
                state.unannounced = Event(TRACK_STARTED, track, now, place_m=_place(place), frames=[frame_index])
                state.inside = {zone: now for zone, inside in in_zones(self.site, place).items() if inside[0]}
            else:
                found += self._lines(track, state, frame_index, place)
                found += self._zones(track, state, frame_index, place)
            state.frame, state.place = frame_index, place
            state.recent.append((now, joints))
            found += state.overstays(track, self.site.zones, now)
            if now >= state.next_fall_check:
                found += state.unsaid_falls(track)
                state.next_fall_check = now + FALL_CHECK_S
            # Announced with their first other event, or once here long enough since the frame it names.
            if state.unannounced is not None and (found or (frame_index - state.unannounced["frames"][0] + 1)
                                                  / self.fps >= self.announced_after_s):
                events.append(state.unannounced)
                state.unannounced = None
            events += found
        return sorted(events, key=lambda e: (e["time_s"], e["track"]))

    def _taken_up(self, carried: CarriedPerson, place: np.ndarray) -> _Person:
        """A carried person's state where the run cut off left it (their last place; here, if it is unknown)."""
        state = _Person(int(round(FALL_WINDOW_S * self.fps)))
        state.frame = int(round(carried.place_s * self.fps))
        state.place = place if carried.place is None else np.asarray(carried.place, dtype=float)
        state.inside = dict(carried.visits)
        state.counted_lines = {line for line, at in carried.crossed.items() if at >= carried.place_s}
        return state

    def give_up(self) -> list[Event]:
        """The carried people not seen again, ended where the run cut off left them (``CarriedPerson.closing``);
        their visits' exits counted."""
        events = [event for person in self._carried.values() for event in person.closing()]
        for event in events:
            if event["event"] == ZONE_LEFT.name and event["zone"] in self.counts:
                self.counts[event["zone"]]["left"] += 1
        self._carried.clear()
        return events

    @property
    def carrying(self) -> set[str]:
        """The carried people not seen again yet."""
        return set(self._carried)

    @property
    def occupants(self) -> dict[str, set[str]]:
        """Who is in each zone now: the people in view, announced, with a visit of it under way (``in_zones`` of
        their latest place), those already in it when their track started too."""
        return {zone.name: {track for track, state in self._people.items()
                            if zone.name in state.inside and state.unannounced is None}
                for zone in self.site.zones}

    def time_in_zones(self, track: str) -> dict[str, float]:
        """Seconds ``track`` has spent in each zone so far: the dwell of its visits that left, and of the one under
        way to its latest frame (a track's whole time in a zone when asked before ``ended``; {} for a track not in
        view)."""
        state = self._people.get(track)
        if state is None:
            return {}
        now = state.frame / self.fps
        return {zone.name: state.spent.get(zone.name, 0.0) + (now - state.inside[zone.name]
                                                               if zone.name in state.inside else 0.0)
                for zone in self.site.zones}

    def ended(self, track: str) -> list[Event]:
        """The track's end (its last frame): a fall still to be found in its last seconds, then "track ended"; a
        visit under way ends with it, unreported. A track not announced yet (``announced_after_s``) with no fall
        either ends unsaid."""
        state = self._people.pop(track, None)
        if state is None:
            return []
        found = state.unsaid_falls(track)
        if state.unannounced is not None and not found:
            return []
        started = [] if state.unannounced is None else [state.unannounced]
        return started + found + [Event(TRACK_ENDED, track, state.frame / self.fps, place_m=_place(state.place),
                                        frames=[state.frame])]

    def _lines(self, track: str, state: _Person, frame_index: int, place: np.ndarray) -> list[Event]:
        events = []
        times, points = np.array([state.frame, frame_index]) / self.fps, np.stack([state.place, place])
        counted, state.counted_lines = state.counted_lines, set()
        for line in self.site.lines:
            if line.name in counted:  # the step from a carried person's last place crosses it again
                continue
            for crossing in line_crossings(times, points, line):
                self.counts[line.name][crossing["direction"]] += 1
                events.append(Event(LINE_CROSSED, track, crossing["time_s"], line=line.name,
                                    direction=crossing["direction"], place_m=crossing["place_m"],
                                    sides_m=crossing["sides_m"], frames=[state.frame, frame_index]))
        return events

    def _zones(self, track: str, state: _Person, frame_index: int, place: np.ndarray) -> list[Event]:
        events, now = [], frame_index / self.fps
        inside = in_zones(self.site, place)
        for zone in self.site.zones:
            was, is_now = zone.name in state.inside, bool(inside[zone.name][0])
            if is_now and not was:
                state.inside[zone.name] = now
                self.counts[zone.name]["entered"] += 1
                events.append(Event(ZONE_ENTERED, track, now, zone=zone.name, place_m=_place(place),
                                    frames=[state.frame, frame_index]))
                occupants = self.occupants[zone.name] | {track}  # an entry announces the one entering
                if zone.max_occupancy is not None and len(occupants) > zone.max_occupancy:
                    events.append(Event(OCCUPANCY_ABOVE_LIMIT, track, now, zone=zone.name, occupancy=len(occupants),
                                        limit=zone.max_occupancy, people=sorted(occupants)))
            elif was and not is_now:
                dwell = now - state.inside.pop(zone.name)
                state.spent[zone.name] = state.spent.get(zone.name, 0.0) + dwell
                state.dwell_reported.discard(zone.name)
                self.counts[zone.name]["left"] += 1
                events.append(Event(ZONE_LEFT, track, now, zone=zone.name, place_m=_place(place),
                                    dwell_s=round(dwell, 3), frames=[state.frame, frame_index]))
        return events


@dataclasses.dataclass
class SiteReplay:
    """A finished world replayed through a ``SiteMonitor``: its ``events`` in time order, the times (F,) of the
    frames anybody was in with, per zone, how many people the monitor had in it at each (``occupancy``), and each
    track's seconds in each zone as the monitor counted them at its end (``time_in_zones``: {track: {zone:
    seconds}}, the visit under way when it ended too)."""

    events: list[Event]
    times: np.ndarray
    occupancy: dict[str, np.ndarray]
    time_in_zones: dict[str, dict[str, float]]


def replay_site(world: World, site: Site) -> SiteReplay:
    """The world's tracks replayed frame by frame through a ``SiteMonitor``, as ``ray3d live`` would have met them:
    every event, each zone's occupancy and each track's time in each zone as the monitor counts them (the one rule
    on both clocks)."""
    world = world.in_frame("world")
    present: dict[int, dict[str, np.ndarray]] = {}
    last: dict[int, list[str]] = {}
    for track, result in world.tracks.items():
        for row, frame in enumerate(result.frames.tolist()):
            present.setdefault(int(frame), {})[str(track)] = result.joints[row]
        last.setdefault(int(result.frames[-1]), []).append(str(track))
    monitor, events, time_in_zones = SiteMonitor(site, world.fps), [], {}
    frames = sorted(present)
    occupancy = {zone.name: np.zeros(len(frames), dtype=int) for zone in site.zones}
    for k, frame in enumerate(frames):
        events += monitor.update(frame, present[frame])
        for zone, inside in monitor.occupants.items():
            occupancy[zone][k] = len(inside)
        for track in last.get(frame, ()):
            time_in_zones[track] = monitor.time_in_zones(track)
            events += monitor.ended(track)
    return SiteReplay(sorted(events, key=lambda e: (e["time_s"], e["track"])), np.array(frames) / world.fps,
                      occupancy, time_in_zones)


def site_events(world: World, site: Site) -> list[Event]:
    """Every event the world's tracks make on the site, in time order (``replay_site``)."""
    return replay_site(world, site).events
