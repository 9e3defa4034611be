"""A site's events as they happen, frame by frame, in the form ``ray3d.site.site_events`` gives them after the
fact and read by the same rules: a line crossed (``line_crossings`` on the step just taken), a zone entered or
left (a visit under way when a track starts is no entry, one under way when it ends no exit), the zones' rules
(occupancy counted from entries and exits; dwell reported when a visit reaches its limit, at the time the offline
report gives it), a fall (``falls`` on the person's last seconds, reported once the person has lain still long
enough for it to count) and track started / ended."""

from __future__ import annotations

from collections import deque

import numpy as np

from ray3d.live.people import PersonNow
from ray3d.site import (FALL_DROP_S, FALL_LYING_WITHIN_S, FALL_STILL_S, Site, falls, line_crossings)

FALL_CHECK_S = 0.5  # how often each person's last seconds are searched for a fall
_FALL_WINDOW_S = FALL_DROP_S + FALL_LYING_WITHIN_S + FALL_STILL_S + 1.0


class _Person:
    def __init__(self, frames: int):
        self.frame = -1
        self.place: np.ndarray | None = None
        self.inside: dict[str, float] = {}   # zone -> when this visit began (its entry time)
        self.recent: deque = deque(maxlen=frames)  # (time, joints) over the longest a fall takes to show
        self.falls_reported_until = -np.inf
        self.dwell_reported: set[str] = set()
        self.next_fall_check = 0.0


class LiveSite:
    """``update(frame index, people)`` -> the events of that frame; ``ended(track, frame index)`` -> a track's
    last events; ``counts`` holds the entries / exits per zone and the crossings per line and direction so far."""

    def __init__(self, site: Site, fps: float):
        self.site, self.fps = site, fps
        self._people: dict[str, _Person] = {}
        self._occupants: dict[str, set[str]] = {zone.name: set() for zone in site.zones}
        self.counts = {**{zone.name: {"entered": 0, "left": 0} for zone in site.zones},
                       **{line.name: {"forward": 0, "back": 0} for line in site.lines}}

    def update(self, frame_index: int, people: list[PersonNow]) -> list[dict]:
        now, events = frame_index / self.fps, []
        for person in people:
            track, place = str(person.track), person.joints[0, :2]
            state = self._people.get(track)
            if state is None:
                state = self._people[track] = _Person(int(round(_FALL_WINDOW_S * self.fps)))
                events.append({"event": "track started", "track": track, "time_s": now,
                               "place_m": place.round(3).tolist(), "frames": [frame_index]})
                state.inside = {zone.name: now for zone in self.site.zones if zone.contains(place)}
            else:
                events += self._moved(track, state, frame_index, place)
            state.frame, state.place = frame_index, place
            state.recent.append((now, person.joints))
            events += self._dwell(track, state, now)
            if now >= state.next_fall_check:
                events += self._falls(track, state)
                state.next_fall_check = now + FALL_CHECK_S
        return sorted(events, key=lambda e: e["time_s"])

    def ended(self, track, frame_index: int) -> list[dict]:
        """The track's end (its last frame): "track ended"; a visit under way ends with it, unreported."""
        state = self._people.pop(str(track), None)
        if state is None:
            return []
        for zone in state.inside:
            self._occupants[zone].discard(str(track))
        return [{"event": "track ended", "track": str(track), "time_s": state.frame / self.fps,
                 "place_m": state.place.round(3).tolist(), "frames": [state.frame]}]

    def _moved(self, track: str, state: _Person, frame_index: int, place: np.ndarray) -> list[dict]:
        events, now = [], frame_index / self.fps
        times, points = np.array([state.frame / self.fps, now]), np.stack([state.place, place])
        for line in self.site.lines:
            for crossing in line_crossings(times, points, line):
                crossing.pop("rows")
                events.append({"event": "line crossed", "line": line.name, "track": track, **crossing,
                               "frames": [state.frame, frame_index]})
                self.counts[line.name][crossing["direction"]] += 1
        for zone in self.site.zones:
            was, is_now = zone.name in state.inside, bool(zone.contains(place))
            if is_now and not was:
                state.inside[zone.name] = now
                self._occupants[zone.name].add(track)
                self.counts[zone.name]["entered"] += 1
                events.append({"event": "zone entered", "zone": zone.name, "track": track, "time_s": now,
                               "place_m": place.round(3).tolist(), "frames": [state.frame, frame_index]})
                if zone.max_occupancy is not None and len(self._occupants[zone.name]) > zone.max_occupancy:
                    events.append({"event": "occupancy above limit", "zone": zone.name, "track": track,
                                   "time_s": now, "occupancy": len(self._occupants[zone.name]),
                                   "limit": zone.max_occupancy, "people": sorted(self._occupants[zone.name])})
            elif was and not is_now:
                dwell = now - state.inside.pop(zone.name)
                self._occupants[zone.name].discard(track)
                state.dwell_reported.discard(zone.name)
                self.counts[zone.name]["left"] += 1
                events.append({"event": "zone left", "zone": zone.name, "track": track, "time_s": now,
                               "place_m": place.round(3).tolist(), "dwell_s": round(dwell, 3),
                               "frames": [state.frame, frame_index]})
        return events

    def _dwell(self, track: str, state: _Person, now: float) -> list[dict]:
        events = []
        for zone in self.site.zones:
            entered = state.inside.get(zone.name)
            if zone.max_dwell_s is None or entered is None or zone.name in state.dwell_reported:
                continue
            if now - entered > zone.max_dwell_s:
                state.dwell_reported.add(zone.name)
                events.append({"event": "dwell above limit", "zone": zone.name, "track": track,
                               "time_s": round(entered + zone.max_dwell_s, 3), "dwell_s": round(now - entered, 3),
                               "limit_s": zone.max_dwell_s})
        return events

    def _falls(self, track: str, state: _Person) -> list[dict]:
        times = np.array([t for t, _ in state.recent])
        found = [fall for fall in falls(times, np.stack([j for _, j in state.recent]))
                 if fall["time_s"] > state.falls_reported_until]
        if found:
            state.falls_reported_until = max(fall["lying_from_s"] + FALL_STILL_S for fall in found)
        return [{"event": "fall", "track": track, **fall} for fall in found]
