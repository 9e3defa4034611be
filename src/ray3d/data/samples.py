"""Training and evaluation samples: windows of world motion seen through cameras, as the networks see them.

For each (clip, frame, camera): the model's window (``ray3d.temporal.Window``, edge-replicated at clip ends)
of pixels and of rays in the NCS, the camera's (height, pitch), and the target frame's targets in the NCS (the
root-relative pose and the root). Everything is vectorised over the batch; nothing loops over frames.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ray3d.data.detector_emulation import (
    body_frames,
    detector_offsets,
    detector_points,
    hidden_joints,
    occluder_rows,
    offset_joints,
    stand_in_hidden,
)
from ray3d.data.motion import MotionSet
from ray3d.data.virtual_cameras import CameraRanges, sample_cameras
from ray3d.errors import InputError
from ray3d.geometry import CameraBatch
from ray3d.geometry import transforms as tf
from ray3d.skeleton import H36M17, LEG_PARTS, Skeleton, conversion_matrix, flip, layout_skeleton, mirror_pixels
from ray3d.temporal import Window, window_indices

# How fast a joint's confidence falls with its 2D noise (a fraction of the person's height in the image).
CONFIDENCE_NOISE_SCALE = 0.05


def leg_swap(skeleton: Skeleton) -> list[int]:
    """The joint order with the two legs swapped (a detector's commonest left/right error)."""
    return [skeleton.flip_permutation[j] if name[2:] in LEG_PARTS else j for j, name in enumerate(skeleton.joint_names)]


@dataclasses.dataclass(frozen=True)
class SampleConfig:
    """How samples are made. The window and the NCS variant are the model's (``ModelConfig.window``,
    ``ModelConfig.remove_roll``), given beside this configuration."""

    flip_probability: float = 0.5
    bone_scale: tuple[float, float] = (0.9, 1.1)   # whole-body factor per sample
    bone_jitter: float = 0.04                      # extra per-bone factor sd (left/right kept equal)
    noise_px: float = 0.0                          # Gaussian 2D noise, like a detector's
    # Detector noise grows with the person's size in the image: a standard deviation of this fraction (drawn
    # per sample) of the person's height in pixels, on top of noise_px.
    noise_height_fraction: tuple[float, float] = (0.0, 0.0)
    # Each joint's noise differs from the sample's level by a log-normal factor of this spread per frame; its
    # confidence falls as its noise grows (``CONFIDENCE_NOISE_SCALE``), to a power drawn per sample, since
    # detectors' scores are calibrated differently.
    noise_spread: float = 0.0
    drop_probability: float = 0.0                  # a dropped joint collapses onto its parent (a detector miss)
    swap_probability: float = 0.0                  # per frame: the detector swaps the left and right leg
    # Where a detector puts a joint differs from the mocap's joint (hips higher and wider, ankle or heel):
    # each seen joint moves by this standard deviation in metres, in the body's frame, the same over a window
    # (the targets stay the mocap's joints).
    joint_offset_m: float = 0.0
    # The measured mean offsets of detectors' joints (``DETECTOR_JOINT_OFFSETS_M``) times a factor drawn per sample
    # from this range (detectors differ), on top of ``joint_offset_m``.
    detector_offset_scale: tuple[float, float] = (0.0, 0.0)
    # The detector layout whose keypoints the model's joints are derived from, as lifting derives them (the
    # H36M-17 pelvis, thorax, spine, neck and head of COCO keypoints); None: the model's own joints are seen.
    seen_as: str | None = None
    # Joints outside their camera's image in the window's target frame are unseen for the whole window (people cut
    # by the picture's edge), as is, for a share ``occluder_probability`` of samples, everything below an image row
    # drawn between the hips and the lower ankle (a counter, a desk, somebody in front). Unseen joints take their
    # parent's place, as lifting puts them (``stand_in_for_unseen``); the hips stay seen.
    hide_outside_image: bool = False
    occluder_probability: float = 0.0
    # A share of samples are children: every bone scaled by a factor from ``child_scale``, the head and neck less.
    child_probability: float = 0.0
    child_scale: tuple[float, float] = (0.6, 0.85)
    cameras: CameraRanges = CameraRanges()
    # More camera ranges, each drawn for a share of the samples (the rest from ``cameras``).
    extra_cameras: tuple[CameraRanges, ...] = ()
    extra_camera_shares: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        if len(self.extra_cameras) != len(self.extra_camera_shares) or sum(self.extra_camera_shares) > 1:
            raise InputError("samples: extra_camera_shares needs one share per extra camera range, together at most 1")


@dataclasses.dataclass
class Batch:
    """One batch (B samples, F frames, J joints), float32 numpy arrays.

    pixels (B, F, J, 2) and rays (B, F, J, 3) in the NCS of the J joints the model sees; pose (B, K, 3) root-relative
    NCS pose of the window's target frame (row 0 is zero) and root (B, 3) NCS root, of the K H36M-17 joints; visible
    (B, F, J) False where a joint was dropped; confidences (B, F, J) in [0, 1]; cameras and world (B, K, 3): the
    cameras and the target frame's world joints, to go back to the world (they describe the scene before any flip).
    """

    pixels: np.ndarray
    rays: np.ndarray
    pose: np.ndarray
    root: np.ndarray
    visible: np.ndarray
    confidences: np.ndarray
    cameras: CameraBatch
    world: np.ndarray

    def take(self, index) -> Batch:
        """The samples at ``index`` (a slice or indices)."""
        return Batch(self.pixels[index], self.rays[index], self.pose[index],
                     self.root[index], self.visible[index], self.confidences[index], self.cameras.take(index),
                     self.world[index])


def scale_bones(positions: np.ndarray, factors: np.ndarray, skeleton: Skeleton = H36M17) -> np.ndarray:
    """Scale every bone of (..., J, 3) poses by (..., J) ``factors`` (factor of the bone ending at each joint),
    keeping bone directions and the root; then re-ground so the lowest ankle stays at its height."""
    scaled = np.empty_like(positions)
    scaled[..., 0, :] = positions[..., 0, :]
    for joint, parent in enumerate(skeleton.parents):
        if parent >= 0:
            bone = positions[..., joint, :] - positions[..., parent, :]
            scaled[..., joint, :] = scaled[..., parent, :] + factors[..., joint, None] * bone
    ankles = [skeleton.index("l_ankle"), skeleton.index("r_ankle")]
    lift = positions[..., ankles, 2].min(-1) - scaled[..., ankles, 2].min(-1)
    scaled[..., 2] += lift[..., None]
    return scaled


def flip_batch(batch: Batch, mask: np.ndarray, skeleton: Skeleton = H36M17) -> Batch:
    """Mirror the samples where (B,) ``mask`` is True: the scene mirrored in the NCS (rays and targets) and its
    image about the principal point; (height, pitch) are unchanged. ``skeleton``: the seen joints' layout (the
    targets are H36M-17). Flipping twice is the identity."""
    def where_masked(flipped: np.ndarray, original: np.ndarray) -> np.ndarray:
        out = original.copy()
        out[mask] = flipped
        return out

    cx = batch.cameras.intrinsics[mask, 2].astype(np.float32)
    return dataclasses.replace(
        batch, pixels=where_masked(mirror_pixels(batch.pixels[mask], cx[:, None, None], skeleton), batch.pixels),
        rays=where_masked(flip(batch.rays[mask], skeleton), batch.rays),
        pose=where_masked(flip(batch.pose[mask], H36M17), batch.pose),
        root=where_masked(batch.root[mask] * np.array([-1.0, 1.0, 1.0], dtype=np.float32), batch.root),
        visible=where_masked(batch.visible[mask][..., list(skeleton.flip_permutation)], batch.visible),
        confidences=where_masked(batch.confidences[mask][..., list(skeleton.flip_permutation)], batch.confidences))


def observe(windows: np.ndarray, cameras: CameraBatch, window: Window, remove_roll: bool = False,
            rng: np.random.Generator | None = None, config: SampleConfig = SampleConfig(),
            layout: str | Skeleton = "h36m17") -> Batch:
    """See (B, F, 17, 3) H36M-17 world windows (F = ``window.frames``) through one camera each and build the
    network's inputs, the joints of ``layout`` as a detector sees them (``detector_points``), and the targets
    of the window's target frame.

    With ``rng`` None nothing random happens (evaluation); otherwise the joint offsets, 2D noise, confidences,
    dropped joints and leg swaps of ``config`` are applied (flip and bone scaling are the generator's).
    ``remove_roll`` selects the gravity-aligned NCS for the rays and targets.
    """
    count, frames, _, _ = windows.shape
    if frames != window.frames:
        raise ValueError(f"observe: windows of {frames} frames for a {window.frames}-frame window")
    skeleton = layout_skeleton(layout)
    seen_skeleton = layout_skeleton(config.seen_as or skeleton)
    seen_points = detector_points(windows, seen_skeleton)
    joints = skeleton.num_joints
    if rng is not None and (config.joint_offset_m > 0 or config.detector_offset_scale[1] > 0):
        offsets = rng.normal(0.0, config.joint_offset_m, (count, seen_skeleton.num_joints, 3))
        offsets += rng.uniform(*config.detector_offset_scale, (count, 1, 1)) * detector_offsets(seen_skeleton)
        seen_points = offset_joints(seen_points, body_frames(windows), offsets, seen_skeleton)
    R, t = cameras.R[:, None, None], cameras.t[:, None, None]
    intrinsics, dist = cameras.intrinsics[:, None, None], cameras.dist[:, None, None]
    has_distortion = cameras.has_distortion
    points_camera = tf.world_to_camera(seen_points, R, t)
    pixels = tf.camera_to_pixels(points_camera, intrinsics, dist if has_distortion else None)
    rays_camera = points_camera / points_camera[..., 2:3]  # exact, no round trip through the lens
    hidden = np.zeros((count, seen_skeleton.num_joints), dtype=bool)
    if rng is not None and (config.hide_outside_image or config.occluder_probability > 0):
        seen = pixels[:, window.target]
        sizes = cameras.sizes if config.hide_outside_image else np.full((count, 2), np.inf)
        hidden = hidden_joints(seen, sizes, occluder_rows(seen, rng, config.occluder_probability, seen_skeleton),
                               seen_skeleton)
    if seen_skeleton.name != skeleton.name:
        # The model's joints from the detector's, as lifting converts them: a derived joint is unseen when any
        # of its sources is. Mean pixels are mean normalised rays for a pinhole (and nearly so through a lens).
        weights = conversion_matrix(seen_skeleton.name, skeleton.name)
        pixels = np.einsum("kj,bfjd->bfkd", weights, np.where(hidden[:, None, :, None], 0.0, pixels))
        rays_camera = np.einsum("kj,bfjd->bfkd", weights, np.where(hidden[:, None, :, None], 0.0, rays_camera))
        hidden = ((weights != 0)[None] & hidden[:, None]).any(-1)
    pixels = stand_in_hidden(pixels, hidden, skeleton)
    rays_camera = stand_in_hidden(rays_camera, hidden, skeleton)
    visible = np.broadcast_to(~hidden[:, None], (count, frames, joints)).copy()
    confidences = np.ones((count, frames, joints))
    if rng is not None and config.drop_probability > 0:
        visible &= rng.random(visible.shape) >= config.drop_probability
        visible[..., 0] = True  # the root has no parent to collapse onto
        parents = [max(p, 0) for p in skeleton.parents]
        pixels = np.where(visible[..., None], pixels, pixels[..., parents, :])
        rays_camera = np.where(visible[..., None], rays_camera, rays_camera[..., parents, :])
    if rng is not None and config.swap_probability > 0:
        swapped = rng.random((count, frames)) < config.swap_probability
        swap = leg_swap(skeleton)
        pixels = np.where(swapped[..., None, None], pixels[..., swap, :], pixels)
        rays_camera = np.where(swapped[..., None, None], rays_camera[..., swap, :], rays_camera)
    noisy = rng is not None and (config.noise_px > 0 or config.noise_height_fraction[1] > 0)
    if noisy:
        seen = pixels[:, window.target]
        span = np.nanmax(np.nanmax(seen, axis=1) - np.nanmin(seen, axis=1), axis=-1)  # (B,) the person's size
        span = np.maximum(np.nan_to_num(span), 1.0)
        level = np.full(count, config.noise_px)
        if config.noise_height_fraction[1] > 0:
            level = level + rng.uniform(*config.noise_height_fraction, count) * span
        sigma = np.broadcast_to(level[:, None, None], (count, frames, joints))
        if config.noise_spread > 0:
            sigma = sigma * np.exp(rng.normal(0.0, config.noise_spread, sigma.shape))
        pixels = pixels + rng.normal(0.0, 1.0, pixels.shape) * sigma[..., None]
        confidences = np.exp(-sigma / span[:, None, None] / CONFIDENCE_NOISE_SCALE)
        if config.noise_spread > 0:
            confidences = confidences ** np.exp(rng.uniform(np.log(0.5), np.log(2.0), (count, 1, 1)))
        # The clean ray is a close start for undistorting the noisy pixel; where a wide lens cannot be
        # inverted there, the clean ray stays.
        noisy_rays = tf.pixels_to_camera_rays(pixels, intrinsics, dist if has_distortion else None,
                                              initial_rays=rays_camera)
        rays_camera = np.where(np.isfinite(noisy_rays), noisy_rays, rays_camera)
    confidences = np.where(visible, confidences, 0.0)
    roll = cameras.roll if remove_roll else None
    rays = tf.rays_camera_to_normalized(rays_camera, cameras.pitch[:, None, None],
                                        None if roll is None else roll[:, None, None])
    index = window.target
    target_camera = tf.world_to_camera(windows[:, index], cameras.R[:, None], cameras.t[:, None])
    target = tf.camera_to_normalized(target_camera, cameras.height[:, None], cameras.pitch[:, None],
                                     None if roll is None else roll[:, None])
    return Batch(
        pixels=pixels.astype(np.float32), rays=rays.astype(np.float32),
        pose=(target - target[:, :1]).astype(np.float32), root=target[:, 0].astype(np.float32),
        visible=visible, confidences=confidences.astype(np.float32), cameras=cameras,
        world=windows[:, index].astype(np.float32))


# A child's head and neck are a larger share of their body: those bones scale by this power of the body's factor.
CHILD_HEAD_POWER = 0.4
_HEAD_BONES = [H36M17.index("neck_nose"), H36M17.index("head")]


def child_factors(count: int, rng: np.random.Generator, config: SampleConfig) -> np.ndarray:
    """(B, 17) bone factors: 1 for adults, for a share ``child_probability`` a child's (``child_scale``)."""
    scale = np.where(rng.random(count) < config.child_probability, rng.uniform(*config.child_scale, count), 1.0)
    factors = np.repeat(scale[:, None], H36M17.num_joints, axis=1)
    factors[:, _HEAD_BONES] = scale[:, None] ** CHILD_HEAD_POWER
    return factors


class SampleGenerator:
    """Random training batches from a motion set: uniform (clip, frame) draws, a random camera per sample,
    bone scaling, flips and detector-like 2D noise, all vectorised."""

    def __init__(self, motion: MotionSet, config: SampleConfig, window: Window, remove_roll: bool = False,
                 seed: int = 0, layout: str = "h36m17"):
        if motion.num_frames == 0:
            raise InputError("SampleGenerator: the motion set has no frames")
        self.motion, self.config, self.window, self.remove_roll = motion, config, window, remove_roll
        self.skeleton = layout_skeleton(layout)
        self.rng = np.random.default_rng(seed)
        clip_of_frame = np.repeat(np.arange(motion.num_clips), motion.clip_lengths())
        self.first = motion.clip_start[:-1][clip_of_frame]
        self.last = motion.clip_start[1:][clip_of_frame] - 1

    def batch(self, size: int) -> Batch:
        rng, config = self.rng, self.config
        targets = rng.integers(0, self.motion.num_frames, size)
        indices = window_indices(targets, self.first[targets], self.last[targets], self.window)
        windows = self.motion.positions[indices].astype(np.float64)  # (B, F, J, 3)
        factors = rng.uniform(*config.bone_scale, (size, 1)) * np.exp(rng.normal(0, config.bone_jitter,
                                                                                (size, H36M17.num_joints)))
        factors[:, H36M17.left] = factors[:, list(H36M17.flip_permutation[i] for i in H36M17.left)]
        if config.child_probability > 0:
            factors *= child_factors(size, rng, config)
        windows = scale_bones(windows, factors[:, None])
        cameras = self.cameras(windows[:, self.window.target, 0])
        batch = observe(windows, cameras, self.window, self.remove_roll, rng, config, self.skeleton)
        return flip_batch(batch, rng.random(size) < config.flip_probability, self.skeleton)

    def cameras(self, targets: np.ndarray) -> CameraBatch:
        """One random camera per (B, 3) target point, from ``cameras`` or, for their shares, ``extra_cameras``."""
        config, rng = self.config, self.rng
        if not config.extra_cameras:
            return sample_cameras(targets, rng, config.cameras)
        shares = np.array([1 - sum(config.extra_camera_shares), *config.extra_camera_shares])
        which = rng.choice(len(shares), len(targets), p=shares / shares.sum())
        parts = [(np.flatnonzero(which == k), ranges)
                 for k, ranges in enumerate((config.cameras, *config.extra_cameras))]
        return CameraBatch.scattered([(index, sample_cameras(targets[index], rng, ranges))
                                      for index, ranges in parts if len(index)], len(targets))


THROUGHPUT_CASES = {
    "pinhole, clean 2D": SampleConfig(),
    "pinhole, 2 px noise + 5% dropped": SampleConfig(noise_px=2.0, drop_probability=0.05),
    "distortion + roll, 2 px noise": SampleConfig(noise_px=2.0, cameras=CameraRanges(distortion_k1=(-0.25, 0.0),
                                                                                       roll_deg=5.0)),
}


def measure_throughput(motion: MotionSet, config: SampleConfig, window: Window, batch_size: int = 1024,
                       repeats: int = 20, seed: int = 0) -> dict:
    """Median time of ``repeats`` batches after one warm-up batch: {"ms_per_batch", "samples_per_s"}."""
    import time

    generator = SampleGenerator(motion, config, window, seed=seed)
    generator.batch(batch_size)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        generator.batch(batch_size)
        times.append(time.perf_counter() - start)
    median = float(np.median(times))
    return {"ms_per_batch": 1e3 * median, "samples_per_s": batch_size / median}
