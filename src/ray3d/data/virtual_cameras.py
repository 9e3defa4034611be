"""Virtual calibrated cameras: the paper's benchmark grids as named sets, the real Human3.6M calibrations, and
a random sampler for training.

Grid geometry (brief section 7): the base camera has the intrinsics of Human3.6M camera 55011271 (pinhole,
1000 x 1000 px) and orbits the world point (0, 0, 1.8) m, looking at it: a camera with yaw psi, pitch theta
and distance d sits at ``target - d * forward(psi, theta)``. Clips are centred on the world origin (mean pelvis
in the floor plane) before they are seen. Every camera has a stable name that encodes its parameters.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ray3d import cameras as camera_tables
from ray3d.errors import InputError
from ray3d.geometry import Camera, CameraBatch, centre_looking_at, pinhole_intrinsics, rotation_from_angles

ORBIT_TARGET = np.array([0.0, 0.0, 1.8])
BASE_CAMERA_ID = "55011271"
IMAGE_SIZE = (1000, 1000)

TRAIN_YAWS_DEG = (60.0, 180.0, 300.0)
TRAIN_PITCHES_DEG = tuple(float(p) for p in range(2, 39, 2))
TRAIN_DISTANCES_M = tuple(np.round(np.linspace(9.05, 11.7, 6), 3))

# Extrinsic test: one factor swept at a time around the base (yaw, pitch, distance); the pitch and distance
# sweeps run at three yaws the training grid never uses.
TEST_BASE_PITCH_DEG, TEST_BASE_DISTANCE_M = 15.0, 10.5
TEST_SWEEP_YAWS_DEG = (30.0, 150.0, 270.0)
ROTATION_SWEEP_YAWS_DEG = tuple(float(y) for y in range(0, 331, 30))
PITCH_SWEEP_DEG = tuple(float(p) for p in range(1, 60, 2))
DISTANCE_SWEEP_M = tuple(np.round(np.arange(9.4, 13.21, 0.76), 2))
INTRINSIC_OFFSETS_PX = tuple(float(o) for o in range(-50, 41, 10))
SCALE_TEST_FACTORS = (0.6, 0.7, 0.8, 0.9, 1.1)
# Cameras as users mount them, beyond the paper's grids: far away and high (surveillance), and low, near eye
# height, looking almost level. They stand on a floor circle about the origin, facing it.
MOUNTED_YAWS_DEG = (30.0, 150.0, 270.0)
FAR_HEIGHTS_M, FAR_DISTANCES_M = (3.0, 6.0, 9.0, 12.0), (15.0, 20.0, 25.0, 30.0, 40.0)
LOW_HEIGHTS_M, LOW_PITCHES_DEG, LOW_DISTANCES_M = (0.8, 1.4, 2.0), (-3.0, 2.0, 8.0), (5.0, 10.0, 20.0, 30.0)
# Near: a room, a clinic, a gym, a counter: 1.5-6 m away, 0.8-3 m high, a wide lens (90 degrees) so that a
# person near the camera is in view at all.
NEAR_HEIGHTS_M, NEAR_DISTANCES_M, NEAR_HFOV_DEG = (0.8, 1.5, 2.2, 3.0), (1.5, 2.5, 4.0, 6.0), 90.0
MOUNTED_AIM_HEIGHT_M = 1.0  # far and near cameras are aimed at this point above the origin
# Level: a room, a shop, a clinic, a corridor: 0.9-1.5 m high, looking 0-15 degrees down at people 2.5-6 m away,
# through a 70-degree lens, in landscape and portrait (people then may be cut by the picture's edge).
LEVEL_HEIGHTS_M, LEVEL_PITCHES_DEG, LEVEL_DISTANCES_M = (0.9, 1.2, 1.5), (0.0, 7.0, 15.0), (2.5, 4.0, 6.0)
LEVEL_HFOV_DEG, LEVEL_IMAGE_SIZES = 70.0, ((1280, 720), (720, 1280))
SET_NAMES = ("train", "extrinsic-test", "intrinsic-test", "scale-test", "h36m", "far-test", "low-test", "near-test",
             "level-test")


def base_intrinsics() -> tuple[float, float, float, float]:
    table = camera_tables.h36m_table()["intrinsics"][BASE_CAMERA_ID]
    return table["fx"], table["fy"], table["cx"], table["cy"]


def orbit_camera(yaw_deg: float, pitch_deg: float, distance_m: float, name: str,
                 intrinsics: tuple[float, float, float, float] | None = None) -> Camera:
    """A pinhole camera looking at ORBIT_TARGET from ``distance_m`` away at the given yaw and pitch."""
    fx, fy, cx, cy = intrinsics or base_intrinsics()
    yaw, pitch = np.radians(yaw_deg), np.radians(pitch_deg)
    return Camera.from_pose(centre_looking_at(ORBIT_TARGET, yaw, pitch, distance_m), yaw, pitch, 0.0, fx, fy, cx, cy,
                            IMAGE_SIZE, name=name)


def mounted_camera(yaw_deg: float, height_m: float, distance_m: float, pitch_deg: float | None, name: str,
                   intrinsics: tuple[float, float, float, float] | None = None,
                   image_size: tuple[int, int] = IMAGE_SIZE) -> Camera:
    """A pinhole camera (the base intrinsics unless given) ``height_m`` above the floor and ``distance_m`` from
    the origin along the floor, facing it at a heading ``yaw_deg``; pitched ``pitch_deg``, or, when None, aimed
    at the point ``MOUNTED_AIM_HEIGHT_M`` above the origin."""
    yaw = np.radians(yaw_deg)
    pitch = np.arctan2(height_m - MOUNTED_AIM_HEIGHT_M, distance_m) if pitch_deg is None else np.radians(pitch_deg)
    centre = centre_looking_at([0.0, 0.0, height_m], yaw, 0.0, distance_m)
    return Camera.from_pose(centre, yaw, pitch, 0.0, *(intrinsics or base_intrinsics()), image_size, name=name)


def _orbit_name(prefix: str, yaw: float, pitch: float, distance: float) -> str:
    return f"{prefix}:yaw{yaw:03.0f}:pitch{pitch:02.0f}:dist{distance:05.2f}"


def _unique(cams: list[Camera]) -> list[Camera]:
    seen, kept = set(), []
    for camera in cams:
        key = (tuple(np.round(camera.center, 6)), tuple(np.round(camera.R.ravel(), 9)),
               tuple(np.round(camera.intrinsics, 6)))
        if key not in seen:
            seen.add(key)
            kept.append(camera)
    return kept


def grid(set_name: str) -> list[Camera]:
    """The named camera set, before the in-image filter."""
    if set_name == "train":
        return [orbit_camera(y, p, d, _orbit_name("train", y, p, d))
                for y in TRAIN_YAWS_DEG for p in TRAIN_PITCHES_DEG for d in TRAIN_DISTANCES_M]
    if set_name == "extrinsic-test":
        p0, d0 = TEST_BASE_PITCH_DEG, TEST_BASE_DISTANCE_M
        rotation = [orbit_camera(y, p0, d0, _orbit_name("rotation", y, p0, d0)) for y in ROTATION_SWEEP_YAWS_DEG]
        pitch = [orbit_camera(y, p, d0, _orbit_name("pitch", y, p, d0))
                 for y in TEST_SWEEP_YAWS_DEG for p in PITCH_SWEEP_DEG]
        distance = [orbit_camera(y, p0, d, _orbit_name("distance", y, p0, d))
                    for y in TEST_SWEEP_YAWS_DEG for d in DISTANCE_SWEEP_M]
        return _unique(rotation + pitch + distance)
    if set_name == "intrinsic-test":
        fx, fy, cx, cy = base_intrinsics()
        y, p, d = TEST_SWEEP_YAWS_DEG[0], TEST_BASE_PITCH_DEG, TEST_BASE_DISTANCE_M
        return [orbit_camera(y, p, d, f"intrinsic:focal{df:+04.0f}:centre{dc:+04.0f}",
                             (fx + df, fy + df, cx + dc, cy + dc))
                for df in INTRINSIC_OFFSETS_PX for dc in INTRINSIC_OFFSETS_PX]
    if set_name == "scale-test":
        # The bodies change (SCALE_TEST_FACTORS), not the cameras: the rotation sweep sees every scale.
        return [c for c in grid("extrinsic-test") if c.name.startswith("rotation:")]
    if set_name == "h36m":
        return camera_tables.h36m_all()
    if set_name == "far-test":
        return [mounted_camera(y, h, d, None, f"far:height{h:04.1f}:dist{d:02.0f}:yaw{y:03.0f}")
                for y in MOUNTED_YAWS_DEG for h in FAR_HEIGHTS_M for d in FAR_DISTANCES_M]
    if set_name == "low-test":
        return [mounted_camera(y, h, d, p, f"low:height{h:03.1f}:pitch{p:+03.0f}:dist{d:02.0f}:yaw{y:03.0f}")
                for y in MOUNTED_YAWS_DEG for h in LOW_HEIGHTS_M for p in LOW_PITCHES_DEG for d in LOW_DISTANCES_M]
    if set_name == "near-test":
        wide = pinhole_intrinsics(IMAGE_SIZE, hfov_deg=NEAR_HFOV_DEG)
        return [mounted_camera(y, h, d, None, f"near:height{h:03.1f}:dist{d:03.1f}:yaw{y:03.0f}", wide)
                for y in MOUNTED_YAWS_DEG for h in NEAR_HEIGHTS_M for d in NEAR_DISTANCES_M]
    if set_name == "level-test":
        return [mounted_camera(y, h, d, p, f"level:height{h:03.1f}:pitch{p:02.0f}:dist{d:03.1f}:yaw{y:03.0f}:"
                               f"{'portrait' if size[1] > size[0] else 'landscape'}",
                               pinhole_intrinsics(size, hfov_deg=LEVEL_HFOV_DEG), size)
                for size in LEVEL_IMAGE_SIZES for y in MOUNTED_YAWS_DEG for h in LEVEL_HEIGHTS_M
                for p in LEVEL_PITCHES_DEG for d in LEVEL_DISTANCES_M]
    raise InputError(f"unknown camera set {set_name!r}; one of {', '.join(SET_NAMES)}")


def centre_clip(positions: np.ndarray) -> np.ndarray:
    """(T, J, 3) clip moved in the floor plane so its mean pelvis position is over the world origin."""
    offset = positions[:, 0, :2].mean(axis=0)
    return positions - np.array([offset[0], offset[1], 0.0], dtype=positions.dtype)


def visibility(cams: list[Camera], clips: list[np.ndarray]) -> np.ndarray:
    """(cameras, clips) bool: camera i sees every joint of every frame of clip j."""
    return np.array([[camera.sees(clip) for clip in clips] for camera in cams], dtype=bool)


def camera_set(set_name: str, clips: list[np.ndarray] | None = None) -> list[Camera]:
    """The named set, keeping only cameras that see every given (already centred) clip entirely."""
    cams = grid(set_name)
    if clips is None:
        return cams
    return [c for c, sees_all in zip(cams, visibility(cams, clips).all(axis=1)) if sees_all]


def cameras_seeing(set_name: str, motion) -> list[Camera]:
    """The named set, keeping only cameras that see every clip of ``motion`` (a ``MotionSet``) entirely once
    the clips are centred, as evaluation places them."""
    return camera_set(set_name, [centre_clip(motion.clip(i)) for i in range(motion.num_clips)])


@dataclasses.dataclass(frozen=True)
class CameraRanges:
    """Ranges of the random training cameras (degrees and metres at the edges, as users think of them).

    Two placements. Without ``height_m`` (the paper's orbit): the camera looks at a point near the person
    (``aim_jitter_m``) from ``distance_m`` away at a pitch in ``pitch_deg`` and any yaw. With ``height_m``
    (cameras as users mount them): the camera hangs ``height_m`` above the floor, ``distance_m`` from the person
    along the floor (drawn log-uniformly: as many near as far cameras per doubling of distance), and is aimed at
    the person give or take ``aim_fov_fraction`` of its half field of view, so the person may stand anywhere in
    the image; its pitch stays in ``pitch_deg`` (cameras that could not see the person then are drawn again).
    The lens comes from ``hfov_deg`` when given, else from ``focal_px``; focal length and principal point vary so
    the model cannot learn one lens. A share ``portrait_probability`` of the cameras is turned on its side
    (``image_size`` swapped: a phone held upright, a corridor camera), the field of view then across the
    narrower side.
    """

    distance_m: tuple[float, float] = (3.5, 14.0)
    pitch_deg: tuple[float, float] = (0.0, 45.0)
    min_height_m: float = 0.3
    roll_deg: float = 0.0
    focal_px: tuple[float, float] = (800.0, 1800.0)
    aspect_jitter: float = 0.01
    principal_offset_px: float = 60.0
    image_size: tuple[int, int] = IMAGE_SIZE
    distortion_k1: tuple[float, float] = (0.0, 0.0)
    aim_jitter_m: float = 0.3
    height_m: tuple[float, float] | None = None
    hfov_deg: tuple[float, float] | None = None
    aim_fov_fraction: float = 0.7
    portrait_probability: float = 0.0


def _image_sizes(count: int, rng: np.random.Generator, ranges: CameraRanges) -> np.ndarray:
    """(B, 2) (width, height) of each camera's image: ``image_size``, or on its side for a portrait share."""
    sizes = np.tile(np.asarray(ranges.image_size, dtype=float), (count, 1))
    if ranges.portrait_probability > 0:
        portrait = rng.random(count) < ranges.portrait_probability
        sizes[portrait] = sizes[portrait][:, ::-1]
    return sizes


def _lenses(sizes: np.ndarray, rng: np.random.Generator, ranges: CameraRanges) -> tuple[np.ndarray, np.ndarray]:
    """(B, 4) intrinsics fx, fy, cx, cy and (B, 5) distortion of random lenses for images of (B, 2) ``sizes``."""
    count = len(sizes)
    width, height = sizes.T
    if ranges.hfov_deg is None:
        focal = rng.uniform(*ranges.focal_px, count)
    else:
        focal = width / 2 / np.tan(np.radians(rng.uniform(*ranges.hfov_deg, count)) / 2)
    aspect = 1 + rng.uniform(-ranges.aspect_jitter, ranges.aspect_jitter, count)
    principal = sizes / 2 + rng.uniform(-ranges.principal_offset_px,
                                                                 ranges.principal_offset_px, (count, 2))
    dist = np.zeros((count, 5))
    dist[:, 0] = rng.uniform(*ranges.distortion_k1, count)
    return np.column_stack([focal, focal * aspect, principal]), dist


def _mounted_poses(targets: np.ndarray, intrinsics: np.ndarray, sizes: np.ndarray, rng: np.random.Generator,
                   ranges: CameraRanges) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centres (B, 3), yaw (B,), pitch (B,)) of cameras mounted at a height and aimed near the target."""
    count = len(targets)
    centre, yaw, pitch = np.empty((count, 3)), np.empty(count), np.empty(count)
    width, height = sizes.T
    todo = np.arange(count)
    low, high = np.radians(ranges.pitch_deg)
    for _ in range(100):
        n = len(todo)
        camera_height = rng.uniform(*ranges.height_m, n)
        distance = np.exp(rng.uniform(*np.log(ranges.distance_m), n))
        bearing = rng.uniform(-np.pi, np.pi, n)  # from the camera towards the person
        half_width = np.arctan(width[todo] / 2 / intrinsics[todo, 0])
        half_height = np.arctan(height[todo] / 2 / intrinsics[todo, 1])
        fraction = ranges.aim_fov_fraction
        elevation = np.arctan2(camera_height - targets[todo, 2], distance)  # positive: the person is below
        wanted = elevation + rng.uniform(-fraction, fraction, n) * half_height
        chosen = np.clip(wanted, low, high)
        centre[todo] = centre_looking_at(np.column_stack([targets[todo, :2], camera_height]), bearing, 0.0, distance)
        yaw[todo] = bearing + rng.uniform(-fraction, fraction, n) * half_width
        pitch[todo] = chosen
        todo = todo[np.abs(chosen - elevation) > fraction * half_height]  # the person would be out of view
        if not len(todo):
            return centre, yaw, pitch
    raise InputError(f"CameraRanges: cameras {ranges.height_m} m high and {ranges.distance_m} m away cannot see the "
                     f"person at pitches {ranges.pitch_deg} deg")


def sample_cameras(targets: np.ndarray, rng: np.random.Generator, ranges: CameraRanges = CameraRanges()) -> CameraBatch:
    """One random camera per (B, 3) world target point (e.g. each sample's target-frame pelvis)."""
    count = len(targets)
    sizes = _image_sizes(count, rng, ranges)
    if ranges.height_m is not None:
        intrinsics, dist = _lenses(sizes, rng, ranges)
        centre, yaw, pitch = _mounted_poses(targets, intrinsics, sizes, rng, ranges)
        roll = np.radians(rng.uniform(-ranges.roll_deg, ranges.roll_deg, count))
    else:
        yaw = rng.uniform(-np.pi, np.pi, count)
        pitch = np.radians(rng.uniform(*ranges.pitch_deg, count))
        roll = np.radians(rng.uniform(-ranges.roll_deg, ranges.roll_deg, count))
        distance = rng.uniform(*ranges.distance_m, count)
        aim = targets + rng.normal(0.0, ranges.aim_jitter_m, (count, 3))
        centre = centre_looking_at(aim, yaw, pitch, distance)
        centre[:, 2] = np.maximum(centre[:, 2], ranges.min_height_m)
        intrinsics, dist = _lenses(sizes, rng, ranges)
    R = rotation_from_angles(yaw, pitch, roll)
    t = -(R @ centre[:, :, None])[..., 0]
    return CameraBatch(R, t, intrinsics, dist, centre[:, 2], pitch, roll, ranges.image_size,
                       None if ranges.portrait_probability == 0 else sizes)
