"""A site file checked against what it is meant for (issue 68): a zone whose sides cross itself is refused where
the file is read (``crossing_sides``); a zone or line that looks drawn in pixels, or lies far from the floor the
cameras see, or that no person ever comes near, is doubted (``site_doubts``: the command line prints each as one
``warning:`` line, asking whether these are metres). A site drawn on a picture's pixels runs for ever with zero
counts; these say so at the start."""

from __future__ import annotations

import dataclasses
from typing import Iterable

import numpy as np

from ray3d.geometry import Camera
from ray3d.site.places import CountingLine, Site, Zone

NEAR_M = 3.0     # a place no person came within this of, or this far from all the floor the cameras see: doubted
FAR_M = 200.0    # a place reaching further than this from the cameras (from the origin without them): doubted
VIEW_M = 100.0   # the floor a camera sees, out to this far from the point below it (people beyond are specks)
_GRID = (65, 49)  # pixels across and down whose rays find the floor a camera sees


@dataclasses.dataclass(frozen=True)
class SiteDoubt:
    """Why a place (``kind`` "zone" or "line", its ``name``) looks wrong: ``reasons``, each a clause."""

    kind: str
    name: str
    reasons: tuple[str, ...]

    @property
    def place(self) -> str:
        return f"{self.kind} {self.name!r}"

    def __str__(self) -> str:
        said = ", ".join(self.reasons[:-1]) + (" and " if len(self.reasons) > 1 else "") + self.reasons[-1]
        return f"{self.place}: {said}: are these metres?"


def crossing_sides(polygon) -> tuple[int, int, np.ndarray] | None:
    """(V, 2) polygon corners, in order around it (the last joined to the first) -> (i, j, where): the first two
    sides that cross or touch, side i running from corner i to the next, and a point they share; None when no two
    sides meet but at their common corner (a simple polygon). A corner repeated (the first again at the end) is
    one corner."""
    points = np.asarray(polygon, dtype=np.float64)
    keep = np.flatnonzero(np.any(points != np.roll(points, 1, axis=0), axis=1))
    points = points[keep]
    n = len(points)
    if n < 4:
        return None
    start, side = points, np.roll(points, -1, axis=0) - points
    scale = max(float(np.ptp(points, axis=0).max()), 1e-9)
    tolerance = 1e-12 * scale ** 2
    for i in range(n - 2):
        others = np.arange(i + 2, n - 1 if i == 0 else n)  # neither side i itself nor its two neighbours
        if not len(others):
            continue
        a, d = start[i], side[i]
        b, e = start[others], side[others]
        o1, o2 = _cross(d, b - a), _cross(d, b + e - a)              # the others' ends against side i
        o3, o4 = _cross(e, a - b), _cross(e, a + d - b)              # side i's ends against the others
        collinear = (np.abs(o1) <= tolerance) & (np.abs(o2) <= tolerance)
        meet = (o1 * o2 <= tolerance ** 2) & (o3 * o4 <= tolerance ** 2) & ~collinear
        length = float(d @ d)
        along = np.stack([(b - a) @ d, (b + e - a) @ d], axis=1) / max(length, 1e-300)
        overlap = collinear & (np.maximum(along.min(axis=1), 0.0) <= np.minimum(along.max(axis=1), 1.0))
        hits = np.flatnonzero(meet | overlap)
        if len(hits):
            k = hits[0]
            denominator = o3[k] - o4[k]
            where = a + (o3[k] / denominator) * d if abs(denominator) > tolerance else b[k]
            return int(keep[i]), int(keep[others[k]]), where
    return None


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def site_doubts(site: Site, cameras: Iterable[Camera] = (), places: np.ndarray | None = None) -> list[SiteDoubt]:
    """The places of ``site`` that look drawn in pixels or somewhere else than where people are: one ``SiteDoubt``
    per place, with every reason found. A place is doubted when it reaches more than ``FAR_M`` from the cameras
    (from the world's origin when no camera is given); when ``cameras`` are given, when it lies more than
    ``NEAR_M`` from all the floor they see (out to ``VIEW_M``); when people's floor ``places`` (N, 2) are given,
    when none came within ``NEAR_M`` of it."""
    cameras = tuple(cameras)
    footprint = np.concatenate([floor_seen(camera) for camera in cameras] or [np.zeros((0, 2))])
    centres = np.array([camera.center[:2] for camera in cameras]).reshape(-1, 2)
    people = None if places is None else _thinned(np.asarray(places, dtype=np.float64).reshape(-1, 2))
    doubts = []
    for place in (*site.zones, *site.lines):
        outline = _outline(place)
        reasons = []
        reference = centres if len(centres) else np.zeros((1, 2))
        reach = float(np.linalg.norm(outline[:, None] - reference[None], axis=-1).min(axis=1).max())
        if reach > FAR_M:
            corner = outline[np.argmax(np.abs(outline).max(axis=1))]
            reasons.append(f"it reaches {reach:.0f} m from {_cameras_named(cameras) if cameras else 'the origin'} (a "
                           f"point at ({corner[0]:g}, {corner[1]:g}))")
        if len(footprint) and not any(_in_view(camera, outline) for camera in cameras):
            apart = distance_to(place, footprint)
            if apart > NEAR_M:
                reasons.append(f"it lies {apart:.0f} m from the floor {_cameras_named(cameras)} "
                               f"{'sees' if len(cameras) == 1 else 'see'}")
        if people is not None:
            apart = distance_to(place, people) if len(people) else np.inf
            if apart > NEAR_M:
                reasons.append("no person was seen at all" if not len(people) else
                               f"no person came within {NEAR_M:g} m of it (the nearest {apart:.0f} m away)")
        if reasons:
            doubts.append(SiteDoubt("zone" if isinstance(place, Zone) else "line", place.name, tuple(reasons)))
    return doubts


def people_places(world) -> np.ndarray:
    """(N, 2) every person's floor place (the pelvis' x, y, as the site's events take it) in every frame of a
    ``World``, world metres."""
    world = world.in_frame("world")
    rows = [np.asarray(result.joints)[:, 0, :2] for result in world.tracks.values()]
    points = np.concatenate(rows) if rows else np.zeros((0, 2))
    return points[np.isfinite(points).all(axis=1)]


def floor_seen(camera: Camera) -> np.ndarray:
    """(N, 2) floor points (z = 0) a camera's pixels see, out to ``VIEW_M`` from the point below it."""
    width, height = camera.image_size
    u, v = np.meshgrid(np.linspace(0, width - 1, _GRID[0]), np.linspace(0, height - 1, _GRID[1]))
    floor = np.asarray(camera.pixels_to_height_plane(np.stack([u.ravel(), v.ravel()], axis=1), 0.0))[:, :2]
    floor = floor[np.isfinite(floor).all(axis=1)]
    return floor[np.linalg.norm(floor - camera.center[:2], axis=1) <= VIEW_M]


def distance_to(place: Zone | CountingLine, points: np.ndarray) -> float:
    """The least distance, metres, from (N, 2) floor points to a zone (0 inside it) or a line's segment."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if not len(points):
        return float("inf")
    if isinstance(place, Zone):
        if np.any(place.contains(points)):
            return 0.0
        starts = place.polygon
        ends = np.roll(place.polygon, -1, axis=0)
    else:
        starts, ends = place.start[None], place.end[None]
    side = ends - starts                                                       # (E, 2)
    offset = points[:, None] - starts[None]                                    # (N, E, 2)
    share = np.clip(np.einsum("nek,ek->ne", offset, side) / np.maximum(np.einsum("ek,ek->e", side, side), 1e-12),
                    0.0, 1.0)
    return float(np.linalg.norm(offset - share[..., None] * side[None], axis=-1).min())


def _outline(place: Zone | CountingLine, step_m: float = 0.5, most: int = 400) -> np.ndarray:
    """(K, 2) points along a zone's sides or a line, every ``step_m`` (at most ``most`` per side)."""
    corners = (np.vstack([place.polygon, place.polygon[:1]]) if isinstance(place, Zone)
               else np.stack([place.start, place.end]))
    pieces = []
    for a, b in zip(corners[:-1], corners[1:]):
        count = int(np.clip(np.ceil(np.linalg.norm(b - a) / step_m), 1, most))
        pieces.append(a + np.linspace(0.0, 1.0, count, endpoint=False)[:, None] * (b - a))
    return np.vstack([*pieces, corners[-1:]])


def _in_view(camera: Camera, points: np.ndarray) -> bool:
    """Whether any floor point (z = 0) lies in the camera's picture (its pinhole, without the lens's distortion,
    which folds far points back in) within ``VIEW_M`` of the point below it."""
    near = points[np.linalg.norm(points - camera.center[:2], axis=1) <= VIEW_M]
    if not len(near):
        return False
    inside = np.asarray(camera.world_to_camera(np.column_stack([near, np.zeros(len(near))])))
    ahead = inside[:, 2] > 1e-6
    fx, fy, cx, cy = camera.intrinsics
    u = fx * inside[ahead, 0] / inside[ahead, 2] + cx
    v = fy * inside[ahead, 1] / inside[ahead, 2] + cy
    width, height = camera.image_size
    return bool(np.any((u >= 0) & (u <= width - 1) & (v >= 0) & (v <= height - 1)))


def _thinned(points: np.ndarray, cell_m: float = 0.25) -> np.ndarray:
    """Floor points, one per ``cell_m`` square (what distances need of thousands of person-frames)."""
    if not len(points):
        return points
    _, first = np.unique(np.floor(points / cell_m).astype(np.int64), axis=0, return_index=True)
    return points[np.sort(first)]


def _cameras_named(cameras: tuple[Camera, ...]) -> str:
    names = [camera.name for camera in cameras if camera.name]
    if len(cameras) == 1:
        return f"camera {names[0]}" if names else "the camera"
    return f"cameras {', '.join(names)}" if len(names) == len(cameras) else "the cameras"
