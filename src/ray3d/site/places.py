"""A site's places: named zones (floor polygons) and directed counting lines, a picture of the floor, and the
geometry of people against them (a line crossed, in which direction; which zones hold a place: ``in_zones``, the one
occupancy rule).

A person's place on the floor plan is their pelvis' (x, y). A line is directed from its ``start`` to its ``end``:
crossing it from its left to its right (seen from above, z up) is "forward", the other way "back". Times are
seconds from the world's frame 0 (``frame / fps``).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ray3d.geometry.floor import Area


@dataclasses.dataclass(frozen=True)
class Zone(Area):
    """A named floor polygon (V, 2) in world metres, with optional rules: the most people at once and the longest
    visit (seconds) before an event says so."""

    name: str
    polygon: np.ndarray
    max_occupancy: int | None = None
    max_dwell_s: float | None = None


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


def in_zones(site: Site, places) -> dict[str, np.ndarray]:
    """(N, 2) floor places -> {zone name: (N,) bool}, which of them lie in each of ``site``'s zones. The one rule of
    who is in a zone: a person is while their latest place lies in it. ``SiteMonitor`` applies it frame by frame
    (its visits, dwell and ``occupants``), the store's record to each person's place once a second."""
    places = np.asarray(places, dtype=np.float64).reshape(-1, 2)
    return {zone.name: np.asarray(zone.contains(places), dtype=bool).reshape(-1) for zone in site.zones}


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
