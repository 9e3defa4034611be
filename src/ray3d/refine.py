"""Track-level absolute refinement: where along its rays a lifted person stands, from three cues weighed by
their uncertainties, with the uncertainty of the answer.

The network's depth is good near the camera and poor far from it; a person's feet rest on the floor while
they stand or walk; and a person keeps one body size. Each frame is moved along the rays by one factor ``s_t``
about the camera centre (``X' = C + s_t (X - C)``), so its joints stay on their rays; the
factors, and one body size per track, are the least-squares solution of the terms below. Given the joints'
observed rays, the root ends on its observed ray, the limbs take the network's shape at the track's size, and each
measured joint then moves towards its own ray by as much as the keypoints are surer of where it is, across the
ray, than the network (``keypoint_error`` against ``pose_lateral_sd_m``): onto it for exact 2D, hardly at all
for a detector's keypoints of a person far away.

- the network: ``log s_t = b`` frame by frame, with a standard deviation that grows with the distance
  (``depth_sd``), where ``b`` is the network's error shared by the whole track;
- the floor: in every frame the detector saw, the lowest ankle lies ``contact_ankle_height_m + f`` above the
  floor under it (``ray3d.geometry.floor``: z = 0, or a declared region, felt over a foot's length), under a
  robust loss, so the frames where no foot touches it (jumps, a foot on a step) cost little; ``f`` is where the
  person's pelvis rests over the floor against the prior, shared by the track;
- the body: ``s_t`` times the frame's body size equals the track's size, which has an adult prior;
- smoothness: the person's distance changes smoothly (the second difference of its log is small), so the
  network's frame-to-frame depth jitter is smoothed away while a steady approach or retreat costs nothing.

Before solving, the floor is put to a test: over every stretch of ``agreement_window_s`` the distance at which
the feet would rest on the floor is compared with the network's; where they differ by more than
``agreement_sigmas`` of their joint uncertainty (a platform, stairs, a bed, a person on a vehicle) the floor
term is dropped for that stretch and the floor's height there is estimated from the network instead
(``ray3d.contact``). The frames in contact are those the solution puts within two standard deviations of the
floor. ``b`` and ``f`` are held at 0 in the solution (each frame's network depth weighed on its own, the contact
height at its prior: measured best on the test performers) and released to their spreads (``depth_bias_sd``: the
network's distance errors of one person are alike from frame to frame, so many frames do not average them away;
``floor_offset_sd_m``) for the answer's uncertainty: the solution's Gauss-Newton covariance, plus the share of the
distance the cues leave (``residual_distance_sd``), is the root's standard deviation along its ray per frame;
across it, a share of the keypoints' error. (A contact call from the ankles' speed was tried first: with
detector jitter on people 100 px tall it found one planted foot in ten frames; docs/RESULTS.md.) Heights and
sizes come from the training performers of the shipped mocap.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import sparse
from scipy.sparse.linalg import splu

from ray3d import body
from ray3d.body import body_sizes, lowest_ankles
from ray3d.contact import floor_agreement
from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.geometry.floor import FLAT_FLOOR, Floor
from ray3d.skeleton import H36M17, Skeleton

EVIDENCE_FPS = 30.0  # per-frame evidence is weighed as if the footage ran at this rate
UNCERTAINTY_SAMPLES = 200  # frames at which the covariance is evaluated; the rest are interpolated
PINNED_SD = 1e-6  # the prior of a term held at its value
# The root, the mean of two hips smoothed in time, errs across its ray by about a third of one keypoint: 0.0104 of
# the size chain on the detector-emulated split (`ray3d-real`, savgol) against a keypoint error of 0.03.
ROOT_KEYPOINT_SHARE = 0.35
UNCERTAINTY_FIELDS = ("depth_bias_sd", "floor_offset_sd_m", "residual_distance_sd")  # what a model measures of itself


@dataclasses.dataclass(frozen=True)
class RefineConfig:
    """The uncertainties the cues are weighed by (metres, or fractions of a distance or size).

    The planted ankle's height and the body-size prior are ``ray3d.body``'s, measured on the training
    performers of the shipped mocap. ``depth_bias_sd`` is (distance m, relative sd) pairs, interpolated: the rms
    of the shipped ``ray3d``'s relative distance error by the distance it predicts, GT 2D, test performers, every
    camera set (docs/RESULTS.md, "Never worse than the network": beyond 15 m it predicts people much too close).
    """

    contact_ankle_height_m: float = body.PLANTED_ANKLE_HEIGHT_M
    ankle_height_sd_m: float = 0.05          # contact-height spread plus the network's ankle error, per frame
    # One person's planted-ankle height against the prior (the floor test), and where their pelvis rests over
    # the floor against the network's pose on the prior (that and the pose's error; the uncertainty), per track.
    contact_height_sd_m: float = 0.02
    floor_offset_sd_m: float = 0.035
    # What the cues leave of the distance's error, as a share of it (the network's pose seen from afar and from
    # above: docs/RESULTS.md, "Never worse than the network"); added to the solution's own uncertainty.
    residual_distance_sd: float = 0.0065
    body_size_m: float = body.ADULT_BODY_SIZE_M      # prior on the size chain of an adult
    body_size_sd: float = body.ADULT_BODY_SIZE_SD    # relative
    frame_size_sd: float = 0.06              # relative error of one frame's predicted body size
    depth_sd: tuple[float, float] = (0.03, 0.006)  # the network's relative depth error: a + b * distance (m)
    depth_bias_sd: tuple[tuple[float, float], ...] = ((0.0, 0.04), (8.0, 0.045), (10.0, 0.06), (12.0, 0.075),
                                                       (15.0, 0.1), (16.0, 0.4), (20.0, 0.6), (60.0, 1.0))
    distance_acceleration_sd: float = 0.3    # of the log of the person's distance, per second^1.5
    robust_scale: float = 2.0                # residuals (in standard deviations) beyond which the loss is linear
    # Across its ray, a joint of the network's shape hung from the root is off by 0.017 m per axis (the shipped
    # `ray3d`, training performers, h36m cameras); a keypoint detector errs by a few per cent of the person's
    # size in the image, which at the person is the same fraction of their size in metres, at any distance.
    pose_lateral_sd_m: float = 0.02
    keypoint_error: float = 0.03             # of the body-size chain, per axis; 0 for exact 2D
    agreement_window_s: float = 2.0          # the stretch over which the floor is tested against the network
    agreement_sigmas: float = 2.0            # a disagreement beyond this many joint sds drops the floor there
    # A floor further from z = 0 (or the declared one) than this is not believed: the network is wrong instead
    # (loading docks, stages and beds stand 0.4-1.3 m high).
    largest_floor_step_m: float = 1.5
    # The floor is tested only where the network places it to within this (1 sd): near, and seen from above.
    floor_test_resolution_m: float = 0.15
    size_cue_margin: float = 0.05            # log size: how much nearer the floor's the size must be to side with it

    @classmethod
    def for_model(cls, document: dict, **changes) -> RefineConfig:
        """The defaults (measured on the shipped ``ray3d``) with what a checkpoint document's ``uncertainty``
        says of its own model (its distance errors by distance, what the cues leave of them), and ``changes``."""
        measured = {key: value for key, value in document.get("uncertainty", {}).items() if key in UNCERTAINTY_FIELDS}
        if "depth_bias_sd" in measured:
            measured["depth_bias_sd"] = tuple(tuple(float(v) for v in pair) for pair in measured["depth_bias_sd"])
        return cls(**{**measured, **changes})

    def network_bias_sd(self, distance: np.ndarray) -> np.ndarray:
        """(...) distances (m) -> (...) the relative sd of the network's distance error shared by a track."""
        at, sd = np.array(self.depth_bias_sd).T
        return np.interp(distance, at, sd)

    def network_frame_sd(self, distance: np.ndarray) -> np.ndarray:
        """(...) distances (m) -> (...) the relative sd of one frame's distance error about the track's."""
        return self.depth_sd[0] + self.depth_sd[1] * np.asarray(distance)


@dataclasses.dataclass(frozen=True)
class Refinement:
    """What the refinement found for one track, frame by frame and as a whole."""

    scale: np.ndarray          # (T,) the factor each frame was moved by along its rays
    contact: np.ndarray        # (T,) whether the lowest ankle ended within two standard deviations of the floor
    floor_cue: np.ndarray      # (T,) whether the feet-on-the-floor term was used in that frame
    floor_height_m: np.ndarray  # (T,) the floor under the feet: the known floor where the floor term was
                                # used, else the network's estimate of where the feet rest (NaN: feet unseen)
    position_sd_m: np.ndarray  # (T, 2) the root's standard deviation along its ray and across it (per axis)
    body_size_m: float         # the track's size chain
    stature_m: float           # the person's estimated stature (``ray3d.body.stature`` of the upright frames)
    stature_sd_m: float

    def summary(self) -> dict:
        """The track's record in world files: totals, and the per-frame contact state and cues."""
        return {"stature_m": round(self.stature_m, 4), "stature_sd_m": round(self.stature_sd_m, 4),
                "stature_interval_m": [round(self.stature_m - 2 * self.stature_sd_m, 4),
                                       round(self.stature_m + 2 * self.stature_sd_m, 4)],
                "body_size_m": round(self.body_size_m, 4),
                "median_scale": round(float(np.median(self.scale)), 4),
                "contact_fraction": round(float(self.contact.mean()), 4),
                "floor_cue_fraction": round(float(self.floor_cue.mean()), 4),
                "position_sd_m": round(float(np.median(self.position_sd_m[:, 0])), 4),
                "frames": {"contact": self.contact.astype(int).tolist(),
                           "floor_cue": self.floor_cue.astype(int).tolist(),
                           "floor_height_m": [None if not np.isfinite(h) else round(float(h), 3)
                                              for h in self.floor_height_m]}}


def joint_directions(camera: Camera, pixels: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """(T, 17, 3) world directions of the H36M-17 joints' observed rays: the ray of the (T, J, 2) pixel of the
    same joint of ``skeleton`` where it has one, else NaN (a joint no detector measures, or a NaN pixel)."""
    pixels = np.asarray(pixels, dtype=np.float64)
    directions = np.full((len(pixels), H36M17.num_joints, 3), np.nan)
    pairs = [(H36M17.index(name), j) for j, name in enumerate(skeleton.joint_names) if name in H36M17.joint_names]
    lifted, measured = (list(index) for index in zip(*pairs))
    observed = pixels[:, measured]
    finite = np.isfinite(observed).all(axis=-1)
    rays = np.full((*observed.shape[:2], 3), np.nan)
    rays[finite] = camera.pixels_to_world_directions(observed[finite])
    directions[:, lifted] = rays
    return directions


def scale_about(joints: np.ndarray, centre: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """(T, J, 3) joints moved along their rays from ``centre`` by (T,) factors."""
    return centre + scale[:, None, None] * (joints - centre)


def network_position_sd(joints: np.ndarray, camera: Camera, config: RefineConfig = RefineConfig()) -> np.ndarray:
    """(T, 17, 3) world joints as the network put them -> (T, 2) the root's standard deviation along its ray
    and across it (per axis), metres, without the refinement: the network's distance error as measured by the
    distance it predicts (``depth_bias_sd``: mostly shared by a track), and the keypoints' error at the person."""
    distance = np.linalg.norm(np.asarray(joints)[:, 0] - camera.center, axis=-1)
    across = np.full(len(distance), _across_sd(config, np.median(body_sizes(joints))))
    return np.stack([config.network_bias_sd(distance) * distance, across], axis=-1)


def _across_sd(config: RefineConfig, body_size: float) -> float:
    """The root's error across its ray: a share of one keypoint's (a floor of 2 mm for exact 2D and rounding)."""
    return max(ROOT_KEYPOINT_SHARE * config.keypoint_error * body_size, 0.002)


class _Problem:
    """The least-squares problem over x = (log s_1..T, log S, b, f)."""

    def __init__(self, joints: np.ndarray, camera: Camera, fps: float, config: RefineConfig, observed: np.ndarray,
                 floored: np.ndarray, floor: Floor):
        self.config, self.count, self.floor = config, len(joints), floor
        self.centre = camera.center
        distance = np.linalg.norm(joints[:, 0] - self.centre, axis=-1)
        self.ankle = lowest_ankles(joints)
        self.floored = floored
        # Neighbouring frames' errors are alike (the network sees overlapping windows), so a second of footage
        # is worth the same evidence at any frame rate; a frame filled in across a gap is no evidence of size.
        self.per_frame = np.sqrt(EVIDENCE_FPS / fps)
        count = self.count
        self.columns = columns = count + 3
        self.size_column, self.bias_column, self.offset_column = count, count + 1, count + 2
        blocks, targets, weights = [], [], []

        def add(matrix, target, weight) -> None:
            blocks.append(sparse.csr_matrix(matrix))
            targets.append(np.broadcast_to(target, matrix.shape[:1]))
            weights.append(np.broadcast_to(weight, matrix.shape[:1]))

        frames = sparse.eye(count, columns)
        add(frames - sparse.csr_matrix((np.ones(count), (np.arange(count), np.full(count, self.bias_column))),
                                       shape=(count, columns)),
            0.0, self.per_frame / config.network_frame_sd(distance))
        if count > 2:  # the distance log(s_t d_t) changes smoothly: its second difference is small
            second = sparse.csr_matrix(sparse.eye(count - 2, columns) - 2 * sparse.eye(count - 2, columns, 1)
                      + sparse.eye(count - 2, columns, 2))
            add(second, -(second[:, :count] @ np.log(distance)), 1 / (config.distance_acceleration_sd * fps ** -1.5))
        add(sparse.hstack([sparse.eye(count), -np.ones((count, 1)), sparse.csr_matrix((count, 2))]),
            -np.log(np.maximum(body_sizes(joints), 1e-3)), observed * self.per_frame / config.frame_size_sd)

        def prior(column: int, target: float, sd: float) -> None:
            add(sparse.csr_matrix(([1.0], ([0], [column])), shape=(1, columns)), target, 1 / sd)

        prior(self.size_column, np.log(config.body_size_m), config.body_size_sd)
        # The network's shared error and the person's contact height are held at 0 in the solution (weighing each
        # frame's network depth on its own and the contact height at its prior measured best on the test
        # performers, docs/RESULTS.md) and released to their spreads for its uncertainty.
        prior(self.bias_column, 0.0, PINNED_SD)
        prior(self.offset_column, 0.0, PINNED_SD)
        self.linear, self.target = sparse.vstack(blocks).tocsr(), np.concatenate(targets)
        self.weight = np.concatenate(weights)
        self.released = self.weight.copy()
        self.released[-2:] = 1 / np.array([float(config.network_bias_sd(np.median(distance))),
                                           config.floor_offset_sd_m])
        rows = np.flatnonzero(self.floored)
        self.robust = np.ones(len(self.target) + len(rows), dtype=bool)
        self.robust[len(self.target) - 3:len(self.target)] = False
        self.floor_scale_rows = sparse.csr_matrix((np.ones(len(rows)), (np.arange(len(rows)), rows)),
                                                  shape=(len(rows), columns))
        self.floor_offset_rows = sparse.csr_matrix((np.ones(len(rows)), (np.arange(len(rows)),
                                                    np.full(len(rows), self.offset_column))), shape=(len(rows), columns))

    def _feet(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The floored frames' factors, lowest ankles moved by them, and the floor's height and gradient there."""
        scale = np.exp(x[:self.count][self.floored])
        feet = self.centre + scale[:, None] * (self.ankle[self.floored] - self.centre)
        height, gradient = self.floor.under_foot(feet[:, :2])
        return scale, feet, height, gradient

    def residuals(self, x: np.ndarray) -> np.ndarray:
        config = self.config
        _, feet, height, _ = self._feet(x)
        above = feet[:, 2] - height - config.contact_ankle_height_m - x[self.offset_column]
        return np.concatenate([self.weight * (self.linear @ x - self.target),
                               above * self.per_frame / config.ankle_height_sd_m])

    def jacobian(self, x: np.ndarray) -> sparse.csr_matrix:
        scale, _, _, gradient = self._feet(x)
        offset = self.ankle[self.floored] - self.centre
        slope = scale * (offset[:, 2] - np.einsum("ti,ti->t", gradient, offset[:, :2]))
        weight = self.per_frame / self.config.ankle_height_sd_m
        return sparse.vstack([sparse.diags(self.weight) @ self.linear,
                              sparse.diags(slope * weight) @ self.floor_scale_rows - weight * self.floor_offset_rows])

    def cost(self, x: np.ndarray) -> float:
        """Robust (soft L1) for the frames' terms: quadratic within ``robust_scale`` standard deviations, linear
        beyond; squares for the priors of the track's size, network error and contact height, which would
        otherwise run away together."""
        scaled = (self.residuals(x) / self.config.robust_scale) ** 2
        return float(np.sum(np.where(self.robust, 2 * (np.sqrt(1 + scaled) - 1), scaled)))

    def _robust_weight(self, residuals: np.ndarray) -> np.ndarray:
        return np.where(self.robust, 1 / np.sqrt(1 + (residuals / self.config.robust_scale) ** 2), 1.0)

    def solve(self, start: np.ndarray, iterations: int = 50, tolerance: float = 1e-10) -> np.ndarray:
        """Gauss-Newton with iteratively reweighted least squares for the robust loss; each step is one sparse
        solve of the (banded) normal equations, so long tracks cost little."""
        x, cost = start.copy(), self.cost(start)
        for _ in range(iterations):
            residuals, jacobian = self.residuals(x), self.jacobian(x)
            weight = self._robust_weight(residuals)
            normal = (jacobian.T @ sparse.diags(weight) @ jacobian).tocsc()
            step = splu(normal + sparse.eye(len(x), format="csc") * 1e-12).solve(-(jacobian.T @ (weight * residuals)))
            for _ in range(20):  # halve a step that does not lower the cost
                trial = self.cost(x + step)
                if trial <= cost:
                    break
                step = step / 2
            else:
                return x
            x, cost = x + step, trial
            if np.abs(step).max() < tolerance:
                break
        return x

    def standard_deviations(self, x: np.ndarray) -> tuple[np.ndarray, float]:
        """(T,) standard deviations of log s at every frame (evaluated at up to ``UNCERTAINTY_SAMPLES`` frames
        and interpolated between them) and that of log S, from the robustly weighted Gauss-Newton information,
        widened by how badly the feet fit the floor: the floor rows' mean squared residual in their standard
        deviations, where it exceeds 1 (lying, jumping, steps the floor does not know)."""
        residuals = self.residuals(x)
        weight = self._robust_weight(residuals)
        floor = residuals[len(self.target):] / self.per_frame
        misfit = np.sqrt(max(1.0, float(np.mean(floor ** 2)))) if len(floor) else 1.0
        pinned, self.weight = self.weight, self.released
        jacobian = self.jacobian(x)
        self.weight = pinned
        information = (jacobian.T @ sparse.diags(weight) @ jacobian).tocsc() + sparse.eye(self.columns) * 1e-12
        lu = splu(information)
        frames = np.unique(np.linspace(0, self.count - 1, min(UNCERTAINTY_SAMPLES, self.count)).astype(int))
        wanted = np.append(frames, self.size_column)
        unit = np.zeros((self.columns, len(wanted)))
        unit[wanted, np.arange(len(wanted))] = 1.0
        variance = np.maximum(lu.solve(unit)[wanted, np.arange(len(wanted))], 0.0)
        sd = misfit * np.sqrt(variance)
        return np.interp(np.arange(self.count), frames, sd[:-1]), float(sd[-1])


def refine_track(joints: np.ndarray, camera: Camera, fps: float, rays: np.ndarray | None = None,
                 observed: np.ndarray | None = None,
                 config: RefineConfig = RefineConfig(),
                 feet_seen: np.ndarray | None = None,
                 floor: Floor = FLAT_FLOOR) -> tuple[np.ndarray, Refinement]:
    """(T, 17, 3) lifted world joints of one person (H36M-17) seen by ``camera`` at ``fps`` -> the refined
    joints and what was found.

    ``rays``: (T, 17, 3) world directions of the joints' observed rays (from their pixels; NaN where a joint
    was not measured, which then stands for the direction towards where the network put it). Given them, the
    cues are read from the joints put on their rays at the network's distances (the body's size in the image
    at a distance is its size), and the result is the root on its observed ray at the distance found with the
    network's pose, scaled to the track's one body size, hung from it, each measured joint moved towards its
    ray (module docstring). Without them every joint moves along the line from the camera through where the
    network put it. ``observed``: (T,) False for frames filled in across a detector's gap, which then follow
    their neighbours. ``feet_seen``: (T,) False for frames whose ankles the detector did not see (legs hidden or
    out of the image), where the feet-on-the-floor cue is not used. ``floor``: the floor under the feet (z = 0
    unless regions are declared).
    """
    joints = np.asarray(joints, dtype=np.float64)
    if joints.ndim != 3 or joints.shape[1:] != (H36M17.num_joints, 3) or not np.isfinite(joints).all():
        raise InputError(f"refine: expected finite (frames, 17, 3) world joints, got shape {joints.shape}")
    if not fps > 0:
        raise InputError(f"refine: fps must be positive, got {fps}")
    centre, count = camera.center, len(joints)
    network = joints
    observed = np.ones(count, dtype=bool) if observed is None else np.asarray(observed, dtype=bool)
    if observed.shape != (count,):
        raise InputError(f"refine: observed must be ({count},), got {observed.shape}")
    if rays is not None:
        if np.shape(rays) != joints.shape:
            raise InputError(f"refine: rays must be shaped like the joints {joints.shape}, got {np.shape(rays)}")
        measured = np.isfinite(rays).all(-1)
        rays = np.where(measured[..., None], rays, joints - centre)
        rays = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
        along = np.einsum("tjk,tjk->tj", joints - centre, rays)
        joints = centre + along[..., None] * rays
    feet_seen = np.ones(count, dtype=bool) if feet_seen is None else np.asarray(feet_seen, dtype=bool)
    floored, resting = floor_agreement(joints, camera, fps, observed & feet_seen, config, floor)
    start = np.concatenate([np.zeros(count), [np.log(np.median(body_sizes(joints))), 0.0, 0.0]])
    problem = _Problem(joints, camera, fps, config, observed, floored, floor)
    x = problem.solve(start)
    scale, body_size = np.exp(x[:count]), float(np.exp(x[problem.size_column]))
    if rays is None:
        refined = scale_about(joints, centre, scale)
    else:
        # The root on its observed ray at the distance found; the limbs in the network's shape at the track's
        # one body size, pulled towards their rays as far as the keypoints are surer than the network.
        root = centre + (scale * along[:, 0])[:, None] * rays[:, 0]
        refined = root[:, None] + body_size / np.median(body_sizes(network)) * (network - network[:, :1])
        across = (config.keypoint_error * body_size) ** 2
        pull = measured * config.pose_lateral_sd_m ** 2 / (config.pose_lateral_sd_m ** 2 + across)
        foot = centre + np.einsum("tjk,tjk->tj", refined - centre, rays)[..., None] * rays  # nearest point on the ray
        refined = refined + pull[..., None] * (foot - refined)
    distance = np.linalg.norm(refined[:, 0] - centre, axis=-1)
    feet = lowest_ankles(refined)
    under = floor.height(feet[:, :2])
    contact = floored & (np.abs(feet[:, 2] - under - config.contact_ankle_height_m - x[problem.offset_column])
                         < 2 * config.ankle_height_sd_m)
    floor_height = np.where(floored, under, resting)
    log_sd, size_sd = problem.standard_deviations(x)
    sizes_up = contact if contact.any() else observed
    stature = body.stature(refined, sizes_up)
    return refined, Refinement(
        scale=scale, contact=contact, floor_cue=floored, floor_height_m=floor_height,
        position_sd_m=np.stack([np.hypot(log_sd, config.residual_distance_sd) * distance,
                                np.full(count, _across_sd(config, body_size))], axis=-1),
        body_size_m=body_size, stature_m=stature,
        stature_sd_m=float(stature * np.hypot(size_sd, config.frame_size_sd / np.sqrt(max(sizes_up.sum(), 1)))))
