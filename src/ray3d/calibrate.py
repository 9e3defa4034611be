"""Camera set-up without a lab: the camera's pose from floor points with known positions (OpenCV solvePnP), or
its height, pitch, roll (and focal length) from a person walking on the floor; and where the floor lies in a
calibrated camera's frame, settled for good (``FloorCheck``): from the lens's height measured by tape, or from two
calibrated cameras' triangulated ankles."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
from scipy.optimize import least_squares

from ray3d.body import ADULT_STATURE_M, ADULT_STATURE_SD_M, AXIS_HEIGHTS, AXIS_JOINTS
from ray3d.errors import InputError
from ray3d.geometry import Camera, parse_image_size
from ray3d.geometry.floor import LARGEST_FLOOR_Z_M
from ray3d.io.detections import TrackDetections
from ray3d.lifting.inputs import prepare_track
from ray3d.lifting.tracks import CameraTracks, people_seen_twice, progress_labels
from ray3d.refine import RefineConfig
from ray3d.refine.ankle_plane import TRIANGULATION_SD_M
from ray3d.skeleton import H36M17, convert_keypoints, layout_skeleton
from ray3d.temporal import check_frame_rate


def from_floor_points(floor_xy: np.ndarray, pixels: np.ndarray, intrinsics: Camera | tuple, image_size=None,
                      dist=None, name: str = "floor-calibrated") -> tuple[Camera, float]:
    """The camera's world pose from floor points: returns (camera, RMS reprojection error in pixels).

    ``intrinsics`` is a Camera (its K, distortion and image size are kept) or (fx, fy, cx, cy) with
    ``image_size``. The world frame is that of the floor points, z up.
    """
    if isinstance(intrinsics, Camera):
        K, dist, image_size = intrinsics.K, intrinsics.dist, intrinsics.image_size
    else:
        fx, fy, cx, cy = intrinsics
        K = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
        dist = np.zeros(5) if dist is None else np.asarray(dist, dtype=np.float64)
    world = np.column_stack([floor_xy, np.zeros(len(floor_xy))]).astype(np.float64)
    spread = np.linalg.svd(floor_xy - floor_xy.mean(axis=0), compute_uv=False)
    if not np.isfinite(spread).all() or spread[-1] <= 1e-3 * max(spread[0], 1e-9):
        raise InputError("calibrate: the floor points lie on one line; the camera's pose needs 4 or more points "
                         "spread over an area of the floor", arguments=("floor_points",))
    try:
        ok, rvec, tvec = cv2.solvePnP(world, pixels.astype(np.float64), K, dist, flags=cv2.SOLVEPNP_ITERATIVE)
    except cv2.error as err:  # degenerate input OpenCV itself refuses
        raise InputError(f"calibrate: OpenCV solvePnP refused these floor points ({err.err})") from None
    if not ok:
        raise InputError("calibrate: OpenCV solvePnP found no pose for these floor points")
    rotation, _ = cv2.Rodrigues(rvec)
    # A planar target has a mirror solution behind the floor; the camera must be above the floor.
    if (-rotation.T @ tvec.ravel())[2] <= 0:
        raise InputError("calibrate: the solution puts the camera below the floor; check the points' order and "
                         "that x, y are a right-handed floor frame (z up)")
    camera = Camera(K, dist, rotation, tvec.ravel(), image_size, name)
    rms = float(np.sqrt(((camera.project(world) - pixels) ** 2).sum(-1).mean()))
    return camera, rms


# How far real walking departs from the upright model: the RMS errors of from_person with the true focal length
# and stature on 40 random (camera, walking clip) pairs of the training performers (`ray3d bench calibration
# --split train --pairs 40 --bootstrap 2 --seed 1`, docs/RESULTS.md). Added in quadrature to the bootstrap.
MODEL_ERROR_SD = {"pitch_deg": 2.9, "roll_deg": 2.3, "height_fraction": 0.10}
MIN_PERSON_FRAMES = 10


@dataclasses.dataclass(frozen=True)
class PersonCalibration:
    """A camera estimated from a walking person, with standard deviations. The world frame is the floor below
    the camera, x along the direction it looks, z up (as ``Camera.from_height_pitch``).

    Each standard deviation combines a block bootstrap over the frames (how consistently they agree), the
    model error (``MODEL_ERROR_SD``: how far real walking departs from the upright model, measured on the
    training performers) and, for the height, the uncertainty of the person's stature."""

    camera: Camera
    height_sd_m: float
    pitch_sd_deg: float
    roll_sd_deg: float
    focal_sd_px: float       # 0 when the focal length was given
    rms_px: float            # reprojection error of the upright-body model over the frames used
    frames_used: int
    people: int = 1          # tracks fitted jointly
    warnings: tuple[str, ...] = ()  # why the estimate may be poor (bad fit, few frames, one distance)

    @property
    def height_m(self) -> float:
        return self.camera.camera_height

    @property
    def pitch_deg(self) -> float:
        return float(np.degrees(self.camera.pitch))

    @property
    def roll_deg(self) -> float:
        return float(np.degrees(self.camera.roll))

    @property
    def focal_px(self) -> float:
        return float(self.camera.K[0, 0])

    def to_dict(self) -> dict:
        estimate = {"height_m": self.height_m, "pitch_deg": self.pitch_deg, "roll_deg": self.roll_deg,
                    "focal_px": self.focal_px}
        fields = {k: v for k, v in dataclasses.asdict(self).items() if k != "camera"}
        return {**estimate, **fields, "warnings": list(self.warnings)}

    def summary(self) -> str:
        focal = (f"focal {self.focal_px:.0f} +- {self.focal_sd_px:.0f} px" if self.focal_sd_px > 0
                 else f"focal {self.focal_px:.0f} px (given)")
        return (f"camera height {self.height_m:.2f} +- {self.height_sd_m:.2f} m, pitch {self.pitch_deg:.1f} +- "
                f"{self.pitch_sd_deg:.1f} deg, roll {self.roll_deg:.1f} +- {self.roll_sd_deg:.1f} deg, {focal}; "
                f"model fit RMS {self.rms_px:.1f} px over {self.frames_used} frames of {self.people} "
                f"{'person' if self.people == 1 else 'people'}")


def person_axis_pixels(keypoints: np.ndarray, layout: str = "h36m17", confidences=None) -> np.ndarray:
    """(T, J, 2) keypoints (optional (T, J) confidences, 0 = missing) -> (T, 4, 2) pixels of the mid-ankle,
    pelvis, thorax and head (NaN where missing)."""
    skeleton = layout_skeleton(layout)
    keypoints = np.asarray(keypoints, dtype=np.float64)
    if keypoints.ndim != 3 or keypoints.shape[1:] != (skeleton.num_joints, 2):
        raise InputError(f"keypoints: expected (frames, {skeleton.num_joints}, 2) for layout {layout}, got "
                         f"{keypoints.shape}")
    if confidences is not None and np.shape(confidences) != keypoints.shape[:2]:
        raise InputError(f"confidences: expected shape {keypoints.shape[:2]}, got {np.shape(confidences)}")
    pixels, _ = convert_keypoints(keypoints, skeleton, confidences)
    return np.stack([pixels[:, [H36M17.index(j) for j in joints]].mean(1) for joints in AXIS_JOINTS.values()], 1)


def from_person(keypoints, image_size: tuple[int, int], person_height: float = ADULT_STATURE_M,
                focal_px: float | None = None, layout: str = "h36m17", person_height_sd: float = ADULT_STATURE_SD_M,
                bootstrap: int = 30, seed: int = 0, max_frames: int = 400, model_error: bool = True,
                confidences=None) -> PersonCalibration:
    """The camera's height, pitch and roll (and focal length when ``focal_px`` is None) from 2D keypoints of
    people standing or walking on the floor, seen by a camera with square pixels and its principal point at
    the image centre. ``keypoints`` is one person's (T, J, 2) or a list of several people's (T_i, J, 2) (with
    ``confidences`` (T, J) or a list alike; 0 = missing), all fitted jointly: people at different distances
    make the focal length observable, and their gaits' and statures' errors average out.

    The model: in every frame a person's mid-ankle, pelvis, thorax and head lie on one vertical line at
    fixed fractions of ``person_height`` (``AXIS_HEIGHTS``). For a candidate camera each point's ray meets the
    horizontal plane at its height; the vertical line stands at the mean of those four floor positions, and
    the four points on it are projected back; the parameters minimise the robust (soft L1) reprojection error
    over the frames. Heights scale with the assumed (mean) stature, angles do not. Frames where somebody bends
    or sits fit the model badly and are down-weighted by the robust loss. The standard deviations combine a
    bootstrap (over people when there are three or more, else over blocks of frames), the model error and the
    stature's spread, the last two shrinking with the number of people. ``warnings`` says when the fit is
    poor instead of returning a confident wrong camera. ``model_error=False`` leaves ``MODEL_ERROR_SD`` out
    (e.g. for a synthetic person who fits the model exactly).
    """
    width, height = parse_image_size(image_size)
    people = list(keypoints) if isinstance(keypoints, (list, tuple)) else [keypoints]
    scores = (list(confidences) if isinstance(confidences, (list, tuple)) else [confidences]) \
        if confidences is not None else [None] * len(people)
    if len(scores) != len(people):
        raise InputError(f"confidences: {len(scores)} arrays for {len(people)} people's keypoints")
    axes = []
    for person, score in zip(people, scores):
        axis = person_axis_pixels(person, layout, score)
        axes.append(axis[np.isfinite(axis).all(axis=(1, 2))])
    usable = sum(len(a) for a in axes)
    if usable < MIN_PERSON_FRAMES:
        raise InputError(f"keypoints: {usable} frame(s) show the ankles, hips, shoulders and head; at "
                         f"least {MIN_PERSON_FRAMES} are needed")
    if not 0.5 < person_height < 2.8:
        raise InputError(f"person_height: expected the person's stature in metres (0.5-2.8), got {person_height}")
    if focal_px is not None and not focal_px > 0:
        raise InputError(f"focal_px: expected a positive focal length in pixels, got {focal_px}")
    # At most max_frames frames in all, taken evenly from each person in proportion to how long they were seen.
    axes = [a[np.linspace(0, len(a) - 1, max(1, round(len(a) * min(1.0, max_frames / usable)))).astype(int)]
            for a in axes if len(a)]
    owner = np.concatenate([np.full(len(a), i) for i, a in enumerate(axes)])
    axis = np.concatenate(axes)
    problem = _PersonProblem(axis, (width, height), person_height, focal_px)
    best = problem.solve_from_grid()
    rng = np.random.default_rng(seed)
    # Frames close in time are not independent: resample whole people, or (fewer than three) ten blocks of frames.
    blocks = ([np.flatnonzero(owner == i) for i in range(len(axes))] if len(axes) >= 3
              else np.array_split(np.arange(len(axis)), min(10, len(axis))))
    estimates = []
    for _ in range(bootstrap):
        chosen = np.concatenate([blocks[i] for i in rng.integers(0, len(blocks), len(blocks))])
        estimates.append(_PersonProblem(axis[chosen], (width, height), person_height, focal_px).solve(best.x))
    spread = np.std(estimates, axis=0) if bootstrap > 1 else np.zeros_like(best.x)
    shrink = 1.0 / np.sqrt(len(axes))  # independent people's gaits and statures average out
    floor = {k: v * shrink for k, v in MODEL_ERROR_SD.items()} if model_error else dict.fromkeys(MODEL_ERROR_SD, 0.0)
    camera = dataclasses.replace(problem.camera(best.x), name="person-calibrated")
    height_sd = camera.camera_height * float(np.linalg.norm([spread[2], shrink * person_height_sd / person_height,
                                                             floor["height_fraction"]]))
    residuals = problem.pixel_residuals(best.x)
    rms = float(np.sqrt(np.nanmean(residuals ** 2) * 2))
    return PersonCalibration(
        camera=camera, height_sd_m=height_sd,
        pitch_sd_deg=float(np.hypot(np.degrees(spread[0]), floor["pitch_deg"])),
        roll_sd_deg=float(np.hypot(np.degrees(spread[1]), floor["roll_deg"])),
        focal_sd_px=float(camera.K[0, 0] * spread[3]) if focal_px is None else 0.0,
        rms_px=rms, frames_used=len(axis), people=len(axes),
        warnings=_fit_warnings(axis, rms, height_sd / camera.camera_height, focal_px is None))


def _fit_warnings(axis: np.ndarray, rms_px: float, height_fraction_sd: float, focal_unknown: bool) -> tuple[str, ...]:
    """What makes a person calibration doubtful: a poor fit of the upright model, few frames, everybody at one
    distance while the focal length is unknown, or a wide uncertainty."""
    tall = np.linalg.norm(axis[:, 3] - axis[:, 0], axis=-1)  # head above the ankles, pixels
    warnings = []
    if rms_px > 0.1 * np.median(tall):
        warnings.append(f"the upright-body model fits poorly (RMS {rms_px:.1f} px, "
                        f"{100 * rms_px / np.median(tall):.0f}% of a person's height): are they bending or sitting, "
                        "or are the keypoints wrong?")
    if len(axis) < 50:
        warnings.append(f"only {len(axis)} upright frames: the estimate rests on little")
    if focal_unknown and np.percentile(tall, 90) < 1.3 * np.percentile(tall, 10):
        warnings.append("everybody stays at about one distance from the camera: the focal length is poorly "
                        "determined; give it (focal_px) if it is known")
    if height_fraction_sd > 0.2:
        warnings.append(f"the camera height is uncertain by {100 * height_fraction_sd:.0f}%")
    return tuple(warnings)


class _PersonProblem:
    """The least-squares problem of ``from_person`` over parameters (pitch, roll, log height[, log focal])."""

    def __init__(self, axis: np.ndarray, image_size: tuple[int, int], person_height: float, focal_px: float | None):
        self.axis, self.image_size, self.focal_px = axis, image_size, focal_px
        self.heights = person_height * np.array(list(AXIS_HEIGHTS.values()))
        self.scale = 0.005 * float(np.hypot(*image_size))  # where the robust loss turns linear, pixels
        width = image_size[0]
        low = [np.radians(-30), np.radians(-45), np.log(0.2)]
        high = [np.radians(89), np.radians(45), np.log(50.0)]
        if focal_px is None:
            low, high = low + [np.log(0.2 * width)], high + [np.log(10.0 * width)]
        self.bounds = (np.array(low), np.array(high))

    def camera(self, x: np.ndarray) -> Camera:
        width, height = self.image_size
        focal = np.exp(x[3]) if self.focal_px is None else self.focal_px
        return Camera.from_pose([0.0, 0.0, np.exp(x[2])], 0.0, x[0], x[1], focal, focal, width / 2, height / 2,
                                self.image_size)

    def pixel_residuals(self, x: np.ndarray) -> np.ndarray:
        """(T, 4, 2) predicted minus observed pixels of the mid-ankle, pelvis, thorax and head."""
        camera = self.camera(x)
        direction = camera.pixels_to_world_directions(self.axis)  # (T, 4, 3)
        centre = camera.center
        # Each point's ray meets the horizontal plane at its height; the body's axis stands at their mean.
        along = (self.heights - centre[2]) / direction[..., 2]
        standing = (centre[:2] + along[..., None] * direction[..., :2]).mean(axis=1)
        points = np.concatenate([np.repeat(standing[:, None], len(self.heights), axis=1),
                                 np.broadcast_to(self.heights[None, :, None], (*along.shape, 1))], axis=-1)
        residuals = camera.project(points) - self.axis
        # A ray that never meets its plane in front of the camera: the candidate camera is wrong.
        valid = (along > 0).all(axis=1)[:, None, None] & np.isfinite(residuals)
        return np.where(valid, residuals, float(max(self.image_size)))

    def solve(self, start: np.ndarray) -> np.ndarray:
        return self._fit(start).x

    def _fit(self, start: np.ndarray):
        start = np.clip(start, self.bounds[0] + 1e-9, self.bounds[1] - 1e-9)
        return least_squares(lambda x: self.pixel_residuals(x).ravel(), start, bounds=self.bounds,
                             loss="soft_l1", f_scale=self.scale, x_scale="jac")

    def solve_from_grid(self):
        """The best of several starts (pitch, camera height and focal length spread over their usual ranges)."""
        width = self.image_size[0]
        focals = [None] if self.focal_px is not None else [0.6 * width, 1.2 * width]
        fits = []
        for pitch in np.radians([5.0, 20.0, 35.0, 50.0]):
            for camera_height in (1.5, 3.0, 6.0):
                for focal in focals:
                    start = [pitch, 0.0, np.log(camera_height)] + ([] if focal is None else [np.log(focal)])
                    fits.append(self._fit(np.array(start)))
        return min(fits, key=lambda fit: fit.cost)


# A tape held to a camera finds the height of its housing; the lens's centre inside it is judged by eye.
TAPE_SD_M = 0.02


@dataclasses.dataclass(frozen=True)
class FloorCheck:
    """Where the floor people stand on lies in a camera file's frame (``floor_z_m``, metres; 0: at its z = 0),
    one sd ``sd_m``, and how it was found: ``how`` "lens height" (``lens_height_m`` by tape) or "two cameras"
    (``people`` seen by both at once over ``seconds``, their planted ankles triangulated)."""

    floor_z_m: float
    sd_m: float
    how: str
    people: int = 0
    seconds: float = 0.0
    lens_height_m: float | None = None

    def message(self, camera: str = "") -> str:
        """One line: where the floor lies against the camera's z = 0, and from what."""
        which = f"camera {camera}'s" if camera else "the camera's"
        source = (f"its lens {self.lens_height_m:.2f} m over it, by tape" if self.how == "lens height" else
                  f"{self.people} {'person' if self.people == 1 else 'people'} seen by both cameras over "
                  f"{self.seconds:.0f} s")
        return (f"{which} floor lies {abs(self.floor_z_m):.2f} +/- {self.sd_m:.2f} m "
                f"{'above' if self.floor_z_m > 0 else 'below'} its z = 0 (from {source})")

    def to_dict(self) -> dict:
        """How it was found: its record beside ``floor_z_m`` in the camera file written."""
        return {key: round(value, 4) if isinstance(value, float) else value
                for key, value in dataclasses.asdict(self).items() if key != "floor_z_m" and value is not None}


def floor_from_lens_height(camera: Camera, lens_height_m: float) -> FloorCheck:
    """The floor of ``camera``'s frame from its lens's height over the floor measured by tape: it lies at
    ``camera.center[2] - lens_height_m`` (a camera file whose z = 0 is on the floor gets about 0)."""
    if isinstance(lens_height_m, bool) or not isinstance(lens_height_m, (int, float, np.integer, np.floating)) \
            or not np.isfinite(lens_height_m) or lens_height_m <= 0:
        raise InputError(f"the lens's height over the floor: expected a positive number of metres, got "
                         f"{lens_height_m!r}", arguments=("lens_height_m",))
    floor_z = float(camera.center[2] - lens_height_m)
    if abs(floor_z) > LARGEST_FLOOR_Z_M:
        raise InputError(f"the lens {lens_height_m:g} m over the floor puts the floor {abs(floor_z):.2f} m "
                         f"{'above' if floor_z > 0 else 'below'} camera {camera.name or ''}'s z = 0 (its lens is "
                         f"{camera.center[2]:.2f} m over it), more than {LARGEST_FLOOR_Z_M:g} m: a height in "
                         "metres, of this camera?", arguments=("lens_height_m",))
    return FloorCheck(floor_z, TAPE_SD_M, "lens height", lens_height_m=float(lens_height_m))


def floor_from_cameras(views: dict, layout: str = "h36m17", fps: float | None = None) -> FloorCheck:
    """The floor of two (or more) calibrated cameras' common world frame from the people they see at once:
    {view name: (tracks, Camera)} as ``Lifter.lift_cameras`` takes them (tracks: {track id: (frame ids (N,),
    pixels (N, J, 2) of ``layout``[, confidences (N, J)])}, every view's frame ids on one clock; ``fps`` their
    rate, default the model's 60). Each person seen by two cameras at once gives the height of their planted
    ankle keypoints, triangulated (``lifting.tracks.people_seen_twice``); less the detector's planted-ankle height
    for ``layout`` (``RefineConfig.keypoint_ankle_height_m``), that is the floor. People are combined by the inverse
    variance of their own spread; the calibrations' share of it (``TRIANGULATION_SD_M``) is every person's alike
    and kept whole (a person three cameras see counts once per pair). No network is run. Refused when nobody was
    seen by two cameras at once."""
    if len(views) < 2:
        raise InputError(f"two cameras that see the same people are needed, got {len(views)}", ("views",))
    if fps is not None:
        check_frame_rate(fps, "the keypoints' frame rate")
    cameras, spans = [], []
    for name, (tracks, camera) in views.items():
        view, span = _rays_of_tracks(name, tracks, camera, layout, fps)
        cameras.append(view)
        spans.append(span)
    crossings = people_seen_twice(list(zip(cameras, spans)))
    if not crossings:
        raise InputError(f"no person was seen by {' and '.join(map(str, views))} at once: "
                         + _why_nobody_was_seen_twice(spans))
    # Each crossing's sd is its own spread and the calibrations' share (hypot): only the first averages over people.
    own = np.array([np.sqrt(max(c.sd_m ** 2 - TRIANGULATION_SD_M ** 2, 1e-8)) for c in crossings])
    weights = 1 / own ** 2
    height = float(np.sum(weights * [c.height_m for c in crossings]) / weights.sum())
    contact = RefineConfig.for_model({}, layout).keypoint_ankle_height_m
    return FloorCheck(height - contact, float(np.hypot(weights.sum() ** -0.5, TRIANGULATION_SD_M)), "two cameras",
                      len(crossings), float(sum(c.seconds for c in crossings)))


def _rays_of_tracks(name, tracks: dict, camera: Camera, layout: str, fps: float | None) -> tuple[CameraTracks, dict]:
    """One camera's tracks made rays as the lifter makes them (``prepare_track``, reading H36M-17 joints as the
    shipped models do) -> its ``CameraTracks`` and {track: its (T,) frame ids}. A track that cannot be used is
    left out; a camera none of whose tracks can be is refused, the first reason given."""
    prepared, spans, failures = {}, {}, []
    for track, entry in tracks.items():
        try:
            spans[track], pixels, confidences = TrackDetections(*entry).dense(f"{name}: track {track}")
            prepared[track] = prepare_track(pixels, camera, confidences, fps, layout, None, lambda skeleton: H36M17)
        except InputError as err:
            failures.append(err)
    if not prepared:
        raise InputError(f"{name}: {failures[0].message}" if failures else f"{name}: no tracks",
                         failures[0].arguments if failures else ())
    return CameraTracks(prepared, camera, progress_labels(prepared, False)), spans


def _why_nobody_was_seen_twice(spans: list[dict]) -> str:
    """What keeps two cameras' tracks ({track: frame ids} each) from showing one person at once."""
    shared = [np.intersect1d(np.concatenate(list(a.values())), np.concatenate(list(b.values())))
              for i, a in enumerate(spans) for b in spans[i + 1:]]
    if not any(len(frames) for frames in shared):
        return ("their frame ids never coincide: the keypoint files must count frames on one clock (the same id at "
                "the same moment)")
    return ("their tracks share frame ids, but no two tracks' pelvis rays cross for half a second with the ankles "
            "seen: do the cameras overlap, and are both calibrated in one world frame?")
