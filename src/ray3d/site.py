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

from ray3d.body import HEAD, PELVIS, POSTURES, postures
from ray3d.geometry.floor import polygon_contains
from ray3d.io.world import World


CHILD_STATURE_M = 1.30  # a person shorter than this is a child
# A fall: the head drops this far within this time, and within the next seconds the person lies on the floor
# (torso over 60 degrees from upright, pelvis this low) and stays put (the pelvis moves less than this) this long.
FALL_DROP_M, FALL_DROP_S = 1.0, 1.0
FALL_LYING_WITHIN_S, FALL_PELVIS_M, FALL_STILL_M, FALL_STILL_S = 2.0, 0.5, 0.5, 2.0


@dataclasses.dataclass(frozen=True)
class Zone:
    """A named floor polygon (V, 2) in world metres, with optional rules: the most people at once and the longest
    visit (seconds) before an event says so."""

    name: str
    polygon: np.ndarray
    max_occupancy: int | None = None
    max_dwell_s: float | None = None

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """(..., 2) -> (...) whether the points lie inside."""
        return polygon_contains(self.polygon, xy)


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


@dataclasses.dataclass(frozen=True, eq=False)
class FloorPlan:
    """A picture of the floor seen from above, (H, W, 3 or 4) uint8, drawn under the site's places: each pixel is
    ``metres_per_pixel`` square, the picture's bottom-left corner lies at ``origin`` (world x, y in metres), its
    columns run along +x and its rows up the picture along +y (the convention of ROS occupancy maps)."""

    image: np.ndarray
    metres_per_pixel: float
    origin: np.ndarray

    def extent(self) -> tuple[float, float, float, float]:
        """(x min, x max, y min, y max) of the picture on the floor, metres."""
        height, width = self.image.shape[:2]
        x, y = float(self.origin[0]), float(self.origin[1])
        return x, x + width * self.metres_per_pixel, y, y + height * self.metres_per_pixel


@dataclasses.dataclass(frozen=True)
class Site:
    zones: tuple[Zone, ...] = ()
    lines: tuple[CountingLine, ...] = ()
    floor_plan: FloorPlan | None = None


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
    """Every event the world's tracks make on the site, in time order: line crossings ("line crossed"), zone
    entries and exits ("zone entered", "zone left", the latter with the visit's dwell), the zones' rules
    ("occupancy above limit", "dwell above limit": a visit still going at the track's end is not counted), falls
    ("fall"), and "track started" / "track ended", each with the track id, the time, the place (metres) and the
    evidence it was read from."""
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
        events += [{"event": "fall", "track": track, **fall} for fall in falls(times, result.joints)]
        events.append({"event": "track started", "track": track, "time_s": float(times[0]),
                       "place_m": points[0].round(3).tolist(), "frames": [int(result.frames[0])]})
        events.append({"event": "track ended", "track": track, "time_s": float(times[-1]),
                       "place_m": points[-1].round(3).tolist(), "frames": [int(result.frames[-1])]})
    events = sorted(events, key=lambda e: (e["time_s"], e["track"]))
    return sorted(events + _rule_events(events, site, world.fps), key=lambda e: (e["time_s"], e["track"]))


def _rule_events(events: list[dict], site: Site, fps: float) -> list[dict]:
    """The zones' rules read off the entry and exit events: "occupancy above limit" when an entry makes the count
    exceed ``max_occupancy``; "dwell above limit" when a visit reaches ``max_dwell_s`` (at that moment)."""
    found = []
    for zone in site.zones:
        mine = [e for e in events if e.get("zone") == zone.name]
        if zone.max_occupancy is not None:
            inside: set[str] = set()
            for event in mine:
                (inside.add if event["event"] == "zone entered" else inside.discard)(event["track"])
                if event["event"] == "zone entered" and len(inside) > zone.max_occupancy:
                    found.append({"event": "occupancy above limit", "zone": zone.name, "track": event["track"],
                                  "time_s": event["time_s"], "occupancy": len(inside), "limit": zone.max_occupancy,
                                  "people": sorted(inside)})
        if zone.max_dwell_s is not None:
            for left in (e for e in mine if e["event"] == "zone left" and e["dwell_s"] > zone.max_dwell_s):
                found.append({"event": "dwell above limit", "zone": zone.name, "track": left["track"],
                              "time_s": round(left["time_s"] - left["dwell_s"] + zone.max_dwell_s, 3),
                              "dwell_s": left["dwell_s"], "limit_s": zone.max_dwell_s})
    return found


def track_summaries(world: World, site: Site) -> list[dict]:
    """Per track: when it was seen (first and last time, seconds), the distance walked on the floor plan (metres,
    between consecutive frames), the mean speed, the time spent in each zone, and the stature with its 95 %
    interval where the refinement ran and its class (``stature_class``)."""
    rows = []
    for track, result in world.in_frame("world").tracks.items():
        times, points = result.frames / result.fps, result.root[:, :2]
        walked = float(np.linalg.norm(np.diff(points, axis=0), axis=-1).sum())
        duration = float(times[-1] - times[0])
        refinement = result.refinement or {}
        row = {"track": track, "first_s": round(float(times[0]), 3), "last_s": round(float(times[-1]), 3),
               "distance_m": round(walked, 3), "mean_speed_m_s": round(walked / duration, 3) if duration > 0 else None,
               "stature_m": refinement.get("stature_m"),
               "stature_interval_m": refinement.get("stature_interval_m"),
               "stature_class": stature_class(refinement.get("stature_m"), refinement.get("stature_interval_m"))}
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


def stature_class(stature_m: float | None, interval_m: list | None) -> str:
    """"adult", "child" (under ``CHILD_STATURE_M``), or "unsure" where the stature's interval straddles it (or
    no stature was estimated)."""
    if stature_m is None or interval_m is None:
        return "unsure"
    low, high = interval_m
    return "adult" if low >= CHILD_STATURE_M else "child" if high < CHILD_STATURE_M else "unsure"


def falls(times: np.ndarray, joints: np.ndarray) -> list[dict]:
    """(T,) seconds and (T, 17, 3) world joints of one track -> its falls: the head drops ``FALL_DROP_M`` within
    ``FALL_DROP_S``, the person then lies on the floor within ``FALL_LYING_WITHIN_S`` (torso over 60 degrees from
    upright, pelvis under ``FALL_PELVIS_M``) and stays there, the pelvis moving less than ``FALL_STILL_M``, for
    ``FALL_STILL_S``. Sitting down (the torso stays upright), bending (the pelvis stays up) and lying down slowly
    are not falls. Each with its time (when the head has dropped ``FALL_DROP_M``), place and evidence."""
    head, pelvis = joints[:, HEAD, 2], joints[:, PELVIS]
    down = (postures(joints) == POSTURES.index("lying")) & (pelvis[:, 2] < FALL_PELVIS_M)
    # The lowest the head gets within FALL_DROP_S after each frame (a reverse cumulative window minimum).
    horizon = np.searchsorted(times, times + FALL_DROP_S + 1e-9, side="right")  # up to FALL_DROP_S, rounding aside
    lowest_ahead = np.array([head[t + 1:end].min() if end > t + 1 else np.inf for t, end in enumerate(horizon)]) \
        if len(times) < 2 or np.ptp(np.diff(times)) > 1e-6 else _window_minimum(head, int(horizon[0]))
    found, resume = [], 0
    for t in np.flatnonzero(head - lowest_ahead >= FALL_DROP_M):
        if t < resume:
            continue
        window = np.arange(t + 1, horizon[t])
        landed = window[np.argmax(head[t] - head[window] >= FALL_DROP_M)]
        first, last = np.searchsorted(times, [times[landed], times[landed] + FALL_LYING_WITHIN_S], side="left")
        lying = first + np.flatnonzero(down[first:last + 1])
        if not len(lying):
            continue
        start = lying[0]
        stop = np.searchsorted(times, times[start] + FALL_STILL_S + 1e-9, side="right")
        still = np.arange(start, stop)
        spread = np.linalg.norm(pelvis[still, :2] - pelvis[start, :2], axis=-1).max()
        if times[still[-1]] - times[start] >= FALL_STILL_S - 1e-9 and down[still].all() and spread < FALL_STILL_M:
            found.append({"time_s": float(times[landed]), "place_m": pelvis[start, :2].round(3).tolist(),
                          "head_drop_m": round(float(head[t] - head[landed]), 3),
                          "drop_s": round(float(times[landed] - times[t]), 3),
                          "lying_from_s": float(times[start]), "still_m": round(float(spread), 3)})
            resume = stop  # one fall, not one per frame of it
    return found


def _window_minimum(values: np.ndarray, first_horizon: int) -> np.ndarray:
    """For evenly spaced frames: the minimum of the ``first_horizon - 1`` values after each (inf at the end)."""
    size = max(first_horizon - 1, 1)
    after = np.append(values[1:], np.full(size, np.inf))
    return np.lib.stride_tricks.sliding_window_view(after, size).min(axis=1)[:len(values)]


SPEED_WINDOW_S = 0.5  # speeds and headings over this span, so that a detector's jitter does not read as motion


def person_frames(world: World, site: Site) -> list[dict]:
    """Per person-frame: the track, frame, time, floor point (x, y, metres), speed (m/s) and heading (degrees from
    +x towards +y) over ``SPEED_WINDOW_S`` around it (None where the person is slower than 0.2 m/s: no heading),
    posture (``ray3d.body.postures``) and the zones the point is in."""
    rows = []
    for track, result in world.in_frame("world").tracks.items():
        times, points = result.frames / result.fps, result.root[:, :2]
        half = SPEED_WINDOW_S / 2
        before = np.searchsorted(times, times - half, side="left")
        after = np.searchsorted(times, times + half, side="right") - 1
        span = np.maximum(times[after] - times[before], 1e-9)
        velocity = (points[after] - points[before]) / span[:, None]
        velocity[after == before] = 0.0
        speed = np.linalg.norm(velocity, axis=-1)
        heading = np.degrees(np.arctan2(velocity[:, 1], velocity[:, 0]))
        classes = postures(result.joints)
        inside = {zone.name: zone.contains(points) for zone in site.zones}
        for k in range(len(times)):
            rows.append({"track": track, "frame": int(result.frames[k]), "time_s": round(float(times[k]), 4),
                         "x_m": round(float(points[k, 0]), 3), "y_m": round(float(points[k, 1]), 3),
                         "speed_m_s": round(float(speed[k]), 3),
                         "heading_deg": round(float(heading[k]), 1) if speed[k] >= 0.2 else None,
                         "posture": POSTURES[classes[k]],
                         "zones": [name for name, flags in inside.items() if flags[k]]})
    return rows


def occupancy(rows: list[dict], site: Site, fps: float) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """From ``person_frames`` rows: the frames' times (F,) and, per zone, how many people were in it at each."""
    frames = np.unique([row["frame"] for row in rows]) if rows else np.zeros(0, dtype=int)
    counts = {zone.name: np.zeros(len(frames), dtype=int) for zone in site.zones}
    for row in rows:
        at = np.searchsorted(frames, row["frame"])
        for name in row["zones"]:
            counts[name][at] += 1
    return frames / fps, counts


def heat_map(rows: list[dict], fps: float, cell_m: float = 0.5) -> tuple[np.ndarray, tuple[float, float]]:
    """Seconds spent per ``cell_m`` square of the floor plan by everybody (from ``person_frames`` rows): (H, W)
    and the (x, y) of the grid's lower-left corner."""
    xy = np.array([[row["x_m"], row["y_m"]] for row in rows]).reshape(-1, 2)
    if not len(xy):
        return np.zeros((0, 0)), (0.0, 0.0)
    low = np.floor(xy.min(axis=0) / cell_m) * cell_m
    cells = np.floor((xy - low) / cell_m).astype(int)
    grid = np.zeros((cells[:, 1].max() + 1, cells[:, 0].max() + 1))
    np.add.at(grid, (cells[:, 1], cells[:, 0]), 1.0 / fps)
    return grid, (float(low[0]), float(low[1]))
