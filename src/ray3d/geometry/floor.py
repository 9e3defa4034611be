"""The floor people stand on: the plane z = 0 of the world frame, except inside declared regions (a stage, a
platform, a step, a ramp), each a polygon on the floor plan carrying a plane ``z = height + gradient . (xy -
anchor)``. Pure NumPy; ``ray3d.io.camera_files.read_floor`` reads regions from a file."""

from __future__ import annotations

import dataclasses

import numpy as np
from matplotlib.path import Path as PolygonPath

from ray3d.errors import InputError

PLANARITY_TOLERANCE_M = 0.02  # vertex heights further than this from one plane are not one region
LARGEST_FLOOR_Z_M = 5.0  # a floor further than this from a camera's z = 0 is no calibration's, nor an estimate's
FOOT_LENGTH_M = 0.25  # the floor under an ankle is felt over a foot's length


def checked_floor_z(value, where: str = "floor_z", arguments: tuple[str, ...] = ("floor_z",)) -> float:
    """Where the floor people stand on lies in a camera's frame (metres; 0: at its z = 0), refused in one
    ``InputError`` naming ``where`` unless a finite number within ``LARGEST_FLOOR_Z_M``."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not np.isfinite(value) or abs(value) > LARGEST_FLOOR_Z_M:
        raise InputError(f"{where}: expected the floor's height in the camera's frame, metres within "
                         f"+/- {LARGEST_FLOOR_Z_M:g}; got {value!r}", arguments=arguments)
    return float(value)


def checked_polygon(polygon, where: str, arguments: tuple[str, ...] = ()) -> np.ndarray:
    """A floor-plan polygon as a (V, 2) float array in metres, refused (naming ``where``) unless it has 3 or more
    finite points and encloses some area."""
    polygon = np.asarray(polygon, dtype=np.float64)
    if polygon.ndim != 2 or polygon.shape[1] != 2 or len(polygon) < 3:
        raise InputError(f"{where}: must be 3 or more [x, y] points in metres, got shape {polygon.shape}",
                         arguments=arguments)
    if not np.isfinite(polygon).all():
        raise InputError(f"{where}: has a non-finite coordinate", arguments=arguments)
    x, y = polygon.T
    if abs(0.5 * np.dot(x, np.roll(y, 1)) - 0.5 * np.dot(y, np.roll(x, 1))) < 1e-4:
        raise InputError(f"{where}: encloses no area", arguments=arguments)
    return polygon


def polygon_contains(polygon: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """(V, 2) polygon, (..., 2) floor-plan points -> (...) whether the points lie inside it."""
    xy = np.asarray(xy, dtype=np.float64)
    return PolygonPath(polygon).contains_points(xy.reshape(-1, 2)).reshape(xy.shape[:-1])


class Area:
    """A place on the floor plan bounded by its ``polygon`` (V, 2), world metres (a floor region, a site's zone)."""

    polygon: np.ndarray

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """(..., 2) -> (...) whether the points lie inside the polygon."""
        return polygon_contains(self.polygon, xy)


@dataclasses.dataclass(frozen=True)
class FloorRegion(Area):
    """A region of floor: ``polygon`` (V, 2) world x, y in metres (V >= 3, no self-check beyond area), at
    ``height_m`` above z = 0 at ``anchor`` (x, y), rising by ``gradient`` (dz/dx, dz/dy) per metre."""

    name: str
    polygon: np.ndarray
    height_m: float
    gradient: tuple[float, float] = (0.0, 0.0)
    anchor: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        where = f"floor region {self.name!r}"
        polygon = checked_polygon(self.polygon, f"{where}: polygon", ("floor",))
        numbers = (self.height_m, *self.gradient, *self.anchor)
        if len(self.gradient) != 2 or len(self.anchor) != 2 or not np.isfinite(numbers).all():
            raise InputError(f"{where}: height, gradient and anchor must be finite numbers", arguments=("floor",))
        if np.hypot(*self.gradient) > 1.0:
            raise InputError(f"{where}: slope {np.degrees(np.arctan(np.hypot(*self.gradient))):.0f} deg is steeper "
                             "than 45 deg; declare stairs as flat steps or as the ramp through the middles of their "
                             "treads",
                             arguments=("floor",))
        object.__setattr__(self, "polygon", polygon)

    @classmethod
    def from_vertex_heights(cls, name: str, polygon, heights) -> FloorRegion:
        """The plane through a polygon's (V,) vertex heights (a ramp or a stage), refused unless they lie on one
        plane within ``PLANARITY_TOLERANCE_M``."""
        polygon, heights = np.asarray(polygon, dtype=np.float64), np.asarray(heights, dtype=np.float64)
        if heights.shape != polygon.shape[:1]:
            raise InputError(f"floor region {name!r}: {len(heights)} vertex heights for {len(polygon)} vertices",
                             arguments=("floor",))
        anchor = polygon.mean(axis=0)
        design = np.column_stack([np.ones(len(polygon)), polygon - anchor])
        (height, *gradient), *_ = np.linalg.lstsq(design, heights, rcond=None)
        off = np.abs(design @ np.array([height, *gradient]) - heights).max()
        if off > PLANARITY_TOLERANCE_M:
            raise InputError(f"floor region {name!r}: vertex heights are {off:.3f} m off one plane; split it into "
                             "planar regions", arguments=("floor",))
        return cls(name, polygon, float(height), tuple(map(float, gradient)), tuple(map(float, anchor)))

    def plane_height(self, xy: np.ndarray) -> np.ndarray:
        """(..., 2) -> (...) the height of this region's plane over those floor-plan points."""
        return self.height_m + (np.asarray(xy) - self.anchor) @ np.asarray(self.gradient)



@dataclasses.dataclass(frozen=True)
class Floor:
    """The floor: z = 0 outside every region; inside, the first region (in the order given) that holds a point
    decides its height."""

    regions: tuple[FloorRegion, ...] = ()

    def region_index(self, xy: np.ndarray) -> np.ndarray:
        """(..., 2) -> (...) the index of the region each point is in, -1 for the plain floor."""
        xy = np.asarray(xy, dtype=np.float64)
        index = np.full(xy.shape[:-1], -1)
        for k, region in reversed(list(enumerate(self.regions))):
            index[region.contains(xy)] = k
        return index

    def height(self, xy: np.ndarray) -> np.ndarray:
        """(..., 2) floor-plan points -> (...) the floor's height under them, metres."""
        return self.height_and_gradient(xy)[0]

    def height_and_gradient(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(..., 2) -> the floor's height (...) and its gradient (..., 2) under the points."""
        xy = np.asarray(xy, dtype=np.float64)
        height, gradient = np.zeros(xy.shape[:-1]), np.zeros(xy.shape)
        index = self.region_index(xy)
        for k, region in enumerate(self.regions):
            inside = index == k
            height[inside] = region.plane_height(xy[inside])
            gradient[inside] = region.gradient
        return height, gradient

    def under_foot(self, xy: np.ndarray, length: float = FOOT_LENGTH_M) -> tuple[np.ndarray, np.ndarray]:
        """(..., 2) ankle points -> the floor's height (...) and gradient (..., 2) as a foot of ``length`` feels
        it: the mean of the heights half a foot either way along x and along y, and their central differences.
        Exact on planes; across a region's edge (a step) it ramps over a foot's length, so that a solver moving
        the foot sees the step coming."""
        xy = np.asarray(xy, dtype=np.float64)
        if not self.regions:
            return np.zeros(xy.shape[:-1]), np.zeros(xy.shape)
        half = length / 2
        shifts = np.array([[half, 0.0], [-half, 0.0], [0.0, half], [0.0, -half]])
        heights = self.height(xy[..., None, :] + shifts)
        gradient = np.stack([heights[..., 0] - heights[..., 1], heights[..., 2] - heights[..., 3]], axis=-1) / length
        return heights.mean(axis=-1), gradient

    def lowered(self, depth_m: float) -> Floor:
        """This floor in the frame whose z = 0 lies ``depth_m`` above this one's (every region ``depth_m`` lower;
        outside them the plain floor stays at z = 0 of the new frame)."""
        return Floor(tuple(dataclasses.replace(r, height_m=r.height_m - depth_m) for r in self.regions))

    def to_dict(self) -> dict:
        return {"regions": [{"name": r.name, "polygon": r.polygon.round(4).tolist(),
                             "vertex_heights_m": np.round(r.plane_height(r.polygon), 4).tolist()}
                            for r in self.regions]}


FLAT_FLOOR = Floor()
