"""From positions to places: a site's named zones (floor polygons) and directed counting lines, and the events a
world's tracks make on them (a line crossed, in which direction; a zone entered or left, and how long each visit
lasted), with the track, the time, the place and the evidence.

A person's place on the floor plan is their pelvis' (x, y). A line is directed from its ``start`` to its ``end``:
crossing it from its left to its right (seen from above, z up) is "forward", the other way "back". Times are
seconds from the world's frame 0 (``frame / fps``).
"""

from __future__ import annotations

import dataclasses
import numpy as np

from ray3d.geometry.floor import FloorRegion
from ray3d.io.world import World


@dataclasses.dataclass(frozen=True)
class Zone:
    """A named floor polygon (V, 2) in world metres."""

    name: str
    polygon: np.ndarray

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """(..., 2) -> (...) whether the points lie inside."""
        return FloorRegion(self.name, self.polygon, 0.0).contains(xy)


@dataclasses.dataclass(frozen=True)
class CountingLine:
    """A named, directed floor segment from ``start`` to ``end`` (world metres)."""

    name: str
    start: np.ndarray
    end: np.ndarray

    def side(self, xy: np.ndarray) -> np.ndarray:
        """(..., 2) -> (...) > 0 left of the line, < 0 right of it (the cross product with its direction)."""
        direction = self.end - self.start
        offset = np.asarray(xy, dtype=np.float64) - self.start
        return direction[0] * offset[..., 1] - direction[1] * offset[..., 0]


@dataclasses.dataclass(frozen=True)
class Site:
    zones: tuple[Zone, ...] = ()
    lines: tuple[CountingLine, ...] = ()


def line_crossings(times: np.ndarray, points: np.ndarray, line: CountingLine) -> list[dict]:
    """(T,) seconds and (T, 2) floor points of one track -> its crossings of ``line``: the time (linearly
    interpolated between the two frames), the direction ("forward": from its left to its right), the place, and
    the evidence: the rows before and after (``rows``) and how far each was from the line, metres (``sides_m``,
    positive on its left)."""
    points = np.asarray(points, dtype=np.float64)
    side = line.side(points)
    left = side > 0  # a point on the line counts as right of it, so that passing through it is one crossing
    crossings = []
    for t in np.flatnonzero(left[:-1] != left[1:]):
        share = side[t] / (side[t] - side[t + 1])
        place = points[t] + share * (points[t + 1] - points[t])
        along = np.dot(place - line.start, line.end - line.start) / np.dot(line.end - line.start, line.end - line.start)
        if 0.0 <= along <= 1.0:  # through the segment, not its extension
            length = np.linalg.norm(line.end - line.start)
            crossings.append({"time_s": float(times[t] + share * (times[t + 1] - times[t])),
                              "direction": "forward" if left[t] else "back", "place_m": place.round(3).tolist(),
                              "rows": [int(t), int(t + 1)],
                              "sides_m": [round(float(side[t]) / length, 3), round(float(side[t + 1]) / length, 3)]})
    return crossings


def zone_visits(times: np.ndarray, points: np.ndarray, zone: Zone) -> list[dict]:
    """(T,) seconds and (T, 2) floor points of one track -> its visits of ``zone``: entered and left (None for a
    visit that begins at the track's start or lasts to its end: unknown), the time spent inside, from the first
    frame inside to the first frame outside (to the last frame inside at the track's end), and the rows of the
    first frame inside and the first outside (None at the track's end)."""
    inside = zone.contains(np.asarray(points, dtype=np.float64))
    visits, start = [], None
    for t in range(len(inside) + 1):
        now = bool(inside[t]) if t < len(inside) else False
        if now and start is None:
            start = t
        elif not now and start is not None:
            until = times[t] if t < len(inside) else times[t - 1]
            visits.append({"entered_s": float(times[start]) if start > 0 else None,
                           "left_s": float(times[t]) if t < len(inside) else None,
                           "dwell_s": float(until - times[start]),
                           "rows": [start, t if t < len(inside) else None]})
            start = None
    return visits


def site_events(world: World, site: Site) -> list[dict]:
    """Every event the world's tracks make on the site, in time order: line crossings ("line crossed") and zone
    entries and exits ("zone entered", "zone left", the latter with the visit's dwell), each with the track id,
    the time, the place (metres) and the evidence (the frames it was read from)."""
    events = []
    for track, result in world.in_frame("world").tracks.items():
        times, points = result.frames / result.fps, result.root[:, :2]
        for line in site.lines:
            for crossing in line_crossings(times, points, line):
                rows = crossing.pop("rows")
                events.append({"event": "line crossed", "line": line.name, "track": track, **crossing,
                               "frames": result.frames[rows].tolist()})
        for zone in site.zones:
            for visit in zone_visits(times, points, zone):
                first, after = visit["rows"]
                if visit["entered_s"] is not None:
                    events.append({"event": "zone entered", "zone": zone.name, "track": track,
                                   "time_s": visit["entered_s"], "place_m": points[first].round(3).tolist(),
                                   "frames": [int(result.frames[first - 1]), int(result.frames[first])]})
                if visit["left_s"] is not None:
                    events.append({"event": "zone left", "zone": zone.name, "track": track, "time_s": visit["left_s"],
                                   "place_m": points[after].round(3).tolist(), "dwell_s": round(visit["dwell_s"], 3),
                                   "frames": [int(result.frames[after - 1]), int(result.frames[after])]})
    return sorted(events, key=lambda e: (e["time_s"], e["track"]))


def track_summaries(world: World, site: Site) -> list[dict]:
    """Per track: when it was seen (first and last time, seconds), the distance walked on the floor plan (metres,
    between consecutive frames), the mean speed, the time spent in each zone, and the stature with its 95 %
    interval where the refinement ran."""
    rows = []
    for track, result in world.in_frame("world").tracks.items():
        times, points = result.frames / result.fps, result.root[:, :2]
        walked = float(np.linalg.norm(np.diff(points, axis=0), axis=-1).sum())
        duration = float(times[-1] - times[0])
        refinement = result.refinement or {}
        row = {"track": track, "first_s": round(float(times[0]), 3), "last_s": round(float(times[-1]), 3),
               "distance_m": round(walked, 3), "mean_speed_m_s": round(walked / duration, 3) if duration > 0 else None,
               "stature_m": refinement.get("stature_m"),
               "stature_interval_m": refinement.get("stature_interval_m")}
        for zone in site.zones:
            row[f"time_in_{zone.name}_s"] = round(sum(v["dwell_s"] for v in zone_visits(times, points, zone)), 3)
        rows.append(row)
    return rows


def zone_summaries(events: list[dict], site: Site) -> list[dict]:
    """Per zone: entries, exits and the visits' dwell (mean and longest, of the visits that left); per line:
    crossings each way."""
    rows = []
    for zone in site.zones:
        mine = [e for e in events if e.get("zone") == zone.name]
        dwell = [e["dwell_s"] for e in mine if e["event"] == "zone left"]
        rows.append({"place": zone.name, "kind": "zone", "entries": sum(e["event"] == "zone entered" for e in mine),
                     "exits": len(dwell), "mean_dwell_s": round(float(np.mean(dwell)), 3) if dwell else None,
                     "longest_dwell_s": round(float(np.max(dwell)), 3) if dwell else None})
    for line in site.lines:
        mine = [e for e in events if e.get("line") == line.name]
        rows.append({"place": line.name, "kind": "line", "forward": sum(e["direction"] == "forward" for e in mine),
                     "back": sum(e["direction"] == "back" for e in mine)})
    return rows
