"""Track-level absolute refinement: where along its rays a lifted person stands, from three cues weighed by
their uncertainties.

The network's depth is good near the camera and poor far from it; a person's feet rest on the floor while
they stand or walk; and a person keeps one body size. Each frame is moved along the rays by one factor ``s_t``
about the camera centre (``X' = C + s_t (X - C)``), so its joints stay on their rays; the
factors, and one body size per track, are the least-squares solution of the terms below. Given the joints'
observed rays, the root ends on its ray, the limbs take the network's shape at the track's size, and each
measured joint then moves towards its own ray by as much as the keypoints are surer of where it is, across the
ray, than the network (``keypoint_error`` against ``pose_lateral_sd_m``): onto it for exact 2D, hardly at all
for a detector's keypoints of a person far away.

- the network: ``log s_t = 0`` with a standard deviation that grows with the distance (``depth_sd``);
- the floor: in every frame the detector saw, the lowest ankle lies ``contact_ankle_height_m`` above the floor,
  under a robust loss, so the frames where no foot touches it (jumps, stairs, a foot on a step) cost little;
- the body: ``s_t`` times the frame's body size equals the track's size, which has an adult prior;
- smoothness: the person's distance changes smoothly (the second difference of its log is small), so the
  network's frame-to-frame depth jitter is smoothed away while a steady approach or retreat costs nothing.

The floor cue is strong when the camera is high above the feet and vanishes when it is at their height; the
size cue is weak but never vanishes; the solution weighs them so. The frames in contact are those the solution
puts within two standard deviations of the floor. (A contact call from the ankles' speed was tried first: with
detector jitter on people 100 px tall it found one planted foot in ten frames; docs/RESULTS.md.) Heights and
sizes come from the training performers of the shipped mocap.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import sparse
from scipy.sparse.linalg import splu

from ray3d import body
from ray3d.body import body_sizes, lowest_ankle_height
from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.skeleton import H36M17, Skeleton

EVIDENCE_FPS = 30.0  # per-frame evidence is weighed as if the footage ran at this rate


@dataclasses.dataclass(frozen=True)
class RefineConfig:
    """The uncertainties the cues are weighed by (metres, or fractions of a distance or size).

    The planted ankle's height and the body-size prior are ``ray3d.body``'s, measured on the training
    performers of the shipped mocap.
    """

    contact_ankle_height_m: float = body.PLANTED_ANKLE_HEIGHT_M
    ankle_height_sd_m: float = 0.05          # contact-height spread plus the network's ankle error
    body_size_m: float = body.ADULT_BODY_SIZE_M      # prior on the size chain of an adult
    body_size_sd: float = body.ADULT_BODY_SIZE_SD    # relative
    frame_size_sd: float = 0.06              # relative error of one frame's predicted body size
    depth_sd: tuple[float, float] = (0.03, 0.006)  # the network's relative depth error: a + b * distance (m)
    distance_acceleration_sd: float = 0.3    # of the log of the person's distance, per second^1.5
    robust_scale: float = 2.0                # residuals (in standard deviations) beyond which the loss is linear
    # Across its ray, a joint of the network's shape hung from the root is off by 0.017 m per axis (the shipped
    # `ray3d`, training performers, h36m cameras); a keypoint detector errs by a few per cent of the person's
    # size in the image, which at the person is the same fraction of their size in metres, at any distance.
    pose_lateral_sd_m: float = 0.02
    keypoint_error: float = 0.03             # of the body-size chain, per axis; 0 for exact 2D


@dataclasses.dataclass(frozen=True)
class Refinement:
    """What the refinement found for one track."""

    scale: np.ndarray          # (T,) the factor each frame was moved by along its rays
    contact: np.ndarray        # (T,) whether the lowest ankle ended within two standard deviations of the floor
    body_size_m: float         # the track's size chain
    stature_m: float           # the person's estimated stature (``ray3d.body.stature`` of the upright frames)
    position_sd_m: float       # median over frames of the root position's standard deviation along its ray

    def summary(self) -> dict:
        return {"stature_m": round(self.stature_m, 4), "body_size_m": round(self.body_size_m, 4),
                "median_scale": round(float(np.median(self.scale)), 4),
                "contact_fraction": round(float(self.contact.mean()), 4),
                "position_sd_m": round(self.position_sd_m, 4)}


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


class _Problem:
    """The least-squares problem over x = (log s_1..T, log S)."""

    def __init__(self, joints: np.ndarray, camera: Camera, fps: float, config: RefineConfig, observed: np.ndarray,
                 feet_seen: np.ndarray):
        self.config, self.count = config, len(joints)
        self.centre = camera.center
        distance = np.linalg.norm(joints[:, 0] - self.centre, axis=-1)
        self.lowest = lowest_ankle_height(joints)
        # The frames the floor term applies to: seen, feet seen, and the camera above the feet.
        self.floored = observed & feet_seen & (self.centre[2] - self.lowest > 0.05)
        # Neighbouring frames' errors are alike (the network sees overlapping windows), so a second of footage
        # is worth the same evidence at any frame rate; a frame filled in across a gap is no evidence of size.
        self.per_frame = np.sqrt(EVIDENCE_FPS / fps)
        count, columns = self.count, self.count + 1
        blocks, targets, weights = [], [], []

        def add(matrix, target, weight) -> None:
            blocks.append(sparse.csr_matrix(matrix))
            targets.append(np.broadcast_to(target, matrix.shape[:1]))
            weights.append(np.broadcast_to(weight, matrix.shape[:1]))

        add(sparse.eye(count, columns), 0.0, self.per_frame / (config.depth_sd[0] + config.depth_sd[1] * distance))
        if count > 2:  # the distance log(s_t d_t) changes smoothly: its second difference is small
            second = sparse.csr_matrix(sparse.eye(count - 2, columns) - 2 * sparse.eye(count - 2, columns, 1)
                      + sparse.eye(count - 2, columns, 2))
            add(second, -(second[:, :count] @ np.log(distance)), 1 / (config.distance_acceleration_sd * fps ** -1.5))
        add(sparse.hstack([sparse.eye(count), -np.ones((count, 1))]), -np.log(np.maximum(body_sizes(joints), 1e-3)),
            observed * self.per_frame / config.frame_size_sd)
        add(sparse.csr_matrix(([1.0], ([0], [count])), shape=(1, columns)), np.log(config.body_size_m),
            1 / config.body_size_sd)
        self.linear, self.target = sparse.vstack(blocks).tocsr(), np.concatenate(targets)
        self.weight = np.concatenate(weights)
        self.floor_rows = sparse.eye(count, columns).tocsr()[np.flatnonzero(self.floored)]

    def residuals(self, x: np.ndarray) -> np.ndarray:
        config = self.config
        scale = np.exp(x[:-1][self.floored])
        floor = self.centre[2] + scale * (self.lowest[self.floored] - self.centre[2])
        return np.concatenate([self.weight * (self.linear @ x - self.target),
                               (floor - config.contact_ankle_height_m) * self.per_frame / config.ankle_height_sd_m])

    def jacobian(self, x: np.ndarray) -> sparse.csr_matrix:
        slope = np.exp(x[:-1][self.floored]) * (self.lowest[self.floored] - self.centre[2])
        return sparse.vstack([sparse.diags(self.weight) @ self.linear,
                              sparse.diags(slope * self.per_frame / self.config.ankle_height_sd_m) @ self.floor_rows])

    def cost(self, x: np.ndarray) -> float:
        """The robust (soft L1) cost: quadratic within ``robust_scale`` standard deviations, linear beyond."""
        scaled = (self.residuals(x) / self.config.robust_scale) ** 2
        return float(np.sum(2 * (np.sqrt(1 + scaled) - 1)))

    def solve(self, start: np.ndarray, iterations: int = 50, tolerance: float = 1e-10) -> np.ndarray:
        """Gauss-Newton with iteratively reweighted least squares for the robust loss; each step is one sparse
        solve of the (banded) normal equations, so long tracks cost little."""
        x, cost = start.copy(), self.cost(start)
        for _ in range(iterations):
            residuals, jacobian = self.residuals(x), self.jacobian(x)
            weight = 1 / np.sqrt(1 + (residuals / self.config.robust_scale) ** 2)
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

    def log_scale_sd(self, x: np.ndarray, samples: int = 25) -> np.ndarray:
        """Standard deviations of log s at up to ``samples`` frames spread over the track (Gauss-Newton)."""
        jacobian = self.jacobian(x)
        information = (jacobian.T @ jacobian).tocsc() + sparse.eye(self.count + 1) * 1e-12
        lu = splu(information)
        frames = np.unique(np.linspace(0, self.count - 1, min(samples, self.count)).astype(int))
        unit = np.zeros((self.count + 1, len(frames)))
        unit[frames, np.arange(len(frames))] = 1.0
        return np.sqrt(np.maximum(lu.solve(unit)[frames, np.arange(len(frames))], 0.0))


def refine_track(joints: np.ndarray, camera: Camera, fps: float, rays: np.ndarray | None = None,
                 observed: np.ndarray | None = None,
                 config: RefineConfig = RefineConfig(),
                 feet_seen: np.ndarray | None = None) -> tuple[np.ndarray, Refinement]:
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
    out of the image), where the feet-on-the-floor cue is not used.
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
    start = np.append(np.zeros(count), np.log(np.median(body_sizes(joints))))
    feet_seen = np.ones(count, dtype=bool) if feet_seen is None else np.asarray(feet_seen, dtype=bool)
    problem = _Problem(joints, camera, fps, config, observed, feet_seen)
    x = problem.solve(start)
    scale, body_size = np.exp(x[:-1]), float(np.exp(x[-1]))
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
    lowest = lowest_ankle_height(refined)
    contact = problem.floored & (np.abs(lowest - config.contact_ankle_height_m) < 2 * config.ankle_height_sd_m)
    return refined, Refinement(
        scale=scale, contact=contact, body_size_m=body_size,
        stature_m=body.stature(refined, contact if contact.any() else observed),
        position_sd_m=float(np.median(problem.log_scale_sd(x) * np.median(distance))))
