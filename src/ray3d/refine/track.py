"""``refine_track``: one person's lifted track moved along its rays to where the cues put it, with the
uncertainty of the answer; and the network's own uncertainty where the refinement does not run."""

from __future__ import annotations

import numpy as np

from ray3d import body
from ray3d.body import body_sizes, lowest_ankles
from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.geometry.floor import FLAT_FLOOR, Floor
from ray3d.refine.config import ROOT_KEYPOINT_SHARE, RefineConfig, Refinement
from ray3d.refine.contact import floor_agreement
from ray3d.refine.problem import TrackProblem
from ray3d.skeleton import H36M17, Skeleton

NEAREST_M = 0.2  # a root nearer the camera than this is the network failing, not a person


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


def _observed_rays(joints: np.ndarray, centre: np.ndarray, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T, 17, 3) joints and their rays' (T, 17, 3) directions (NaN: unmeasured) -> the unit rays (an unmeasured
    joint's: towards where the network put it) and (T, 17) each joint's distance along its ray."""
    rays = np.where(np.isfinite(rays).all(-1)[..., None], rays, joints - centre)
    rays = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    return rays, np.einsum("tjk,tjk->tj", joints - centre, rays)


def on_observed_rays(joints: np.ndarray, centre: np.ndarray, rays: np.ndarray) -> np.ndarray:
    """(T, 17, 3) joints as the network put them -> each moved onto its observed ray (``rays``: (T, 17, 3)
    directions, NaN where unmeasured) at the network's distance along it: the pose the keypoints show."""
    rays, along = _observed_rays(np.asarray(joints, dtype=np.float64), centre, rays)
    return centre + along[..., None] * rays


def scale_about(joints: np.ndarray, centre: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """(T, J, 3) joints moved along their rays from ``centre`` by (T,) factors."""
    return centre + scale[:, None, None] * (joints - centre)


def network_position_sd(joints: np.ndarray, camera: Camera, config: RefineConfig = RefineConfig()) -> np.ndarray:
    """(T, 17, 3) world joints as the network put them -> (T, 2) the root's standard deviation along its ray
    and across it (per axis), metres, without the refinement: the network's distance error as measured by the
    distance it predicts (``depth_bias_sd``: mostly shared by a track), and the keypoints' error at the person."""
    distance = np.linalg.norm(np.asarray(joints)[:, 0] - camera.center, axis=-1)
    across = np.full(len(distance), _across_sd(config, np.median(body_sizes(joints))))
    along = np.hypot(config.network_bias_sd(distance) * distance, config.root_definition_sd_m)
    return np.stack([along, across], axis=-1)


def _across_sd(config: RefineConfig, body_size: float) -> float:
    """The root's error across its ray: a share of one keypoint's (a floor of 2 mm for exact 2D and rounding) and
    how far the keypoints' mid-hips stand from a skeleton's pelvis (``root_definition_sd_m``)."""
    return float(np.hypot(max(ROOT_KEYPOINT_SHARE * config.keypoint_error * body_size, 0.002),
                          config.root_definition_sd_m))


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
    out of the image), where the feet-on-the-floor cue is not used and, if the person is upright and the head
    seen, the head's height cue is. ``floor``: the floor under the feet (z = 0
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
        rays, along = _observed_rays(joints, centre, rays)
        # A network that put a person at (or behind) the camera says nothing of where they are: such frames take
        # the track's typical distances and follow their neighbours.
        degenerate = along[:, 0] < NEAREST_M
        if degenerate.all():
            raise InputError("refine: the network put the person at the camera in every frame")
        along[degenerate] = np.median(along[~degenerate], axis=0)
        observed = observed & ~degenerate
        joints = centre + along[..., None] * rays
    feet_seen = np.ones(count, dtype=bool) if feet_seen is None else np.asarray(feet_seen, dtype=bool)
    floored, resting = floor_agreement(joints, camera, fps, observed & feet_seen, config, floor)
    head_seen = observed if rays is None else observed & measured[:, body.HEAD]
    upright = body.postures(joints, floor.height(lowest_ankles(joints)[:, :2])) == body.POSTURES.index("upright")
    headed = head_seen & upright & ~feet_seen
    start = np.concatenate([np.zeros(count), [np.log(np.median(body_sizes(joints))), 0.0, 0.0, 0.0]])
    problem = TrackProblem(joints, camera, fps, config, observed, floored, floor, headed)
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
    # The drop from the camera to the plane the feet rest on, by which an error of that plane scales the distance.
    drop = np.maximum(centre[2] - floor.height(feet[:, :2]) - config.contact_ankle_height_m, 0.1)
    under = floor.height(feet[:, :2])
    contact = floored & (np.abs(feet[:, 2] - under - config.contact_ankle_height_m - x[problem.offset_column])
                         < 2 * config.ankle_height_sd_m)
    floor_height = np.where(floored, under, resting)
    log_sd, size_sd = problem.standard_deviations(x)
    sizes_up = contact if contact.any() else observed
    # The limbs were pulled towards the keypoints' rays: the ankles stand where the keypoints put them.
    stature = body.stature(refined, sizes_up, config.contact_ankle_height_m - body.PLANTED_ANKLE_HEIGHT_M)
    return refined, Refinement(
        scale=scale, contact=contact, floor_cue=floored, floor_height_m=floor_height,
        position_sd_m=np.stack([np.linalg.norm([np.hypot(log_sd, config.residual_distance_sd) * distance,
                                                np.full(count, config.root_definition_sd_m),
                                                config.ankle_plane_sd_m * distance / drop], axis=0),
                                np.full(count, _across_sd(config, body_size))], axis=-1),
        cue_shares=problem.cue_shares(x),
        body_size_m=body_size, stature_m=stature,
        stature_sd_m=float(stature * np.hypot(size_sd, config.frame_size_sd / np.sqrt(max(sizes_up.sum(), 1)))))
