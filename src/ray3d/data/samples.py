"""Training and evaluation samples: windows of world motion seen through cameras, as the networks see them.

For each (clip, frame, camera): the model's window (``ray3d.temporal.Window``, edge-replicated at clip ends)
of pixels and of rays in the NCS, the camera's (height, pitch), and the target frame's targets in the NCS (the
root-relative pose and the root). Everything is vectorised over the batch; nothing loops over frames.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ray3d.data.motion import MotionSet
from ray3d.data.virtual_cameras import CameraRanges, sample_cameras
from ray3d.errors import InputError
from ray3d.geometry import CameraBatch
from ray3d.geometry import transforms as tf
from ray3d.skeleton import H36M17, Skeleton, flip, mirror_pixels
from ray3d.temporal import Window, window_indices

# The joint order with the two legs swapped (a detector's commonest left/right error).
LEG_SWAP = [H36M17.flip_permutation[j] if any(p in name for p in ("hip", "knee", "ankle")) else j
            for j, name in enumerate(H36M17.joint_names)]


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
    drop_probability: float = 0.0                  # a dropped joint collapses onto its parent (a detector miss)
    swap_probability: float = 0.0                  # per frame: the detector swaps the left and right leg
    # Where a detector puts a joint differs from the mocap's joint (hips higher and wider, ankle or heel):
    # each joint moves by this standard deviation in metres, in the body's frame, the same over a window.
    joint_offset_m: float = 0.0
    cameras: CameraRanges = CameraRanges()


@dataclasses.dataclass
class Batch:
    """One batch (B samples, F frames, J joints), float32 numpy arrays.

    pixels (B, F, J, 2); rays (B, F, J, 3) in the NCS; camera_params (B, 2) = (height m, pitch rad);
    pose (B, J, 3) root-relative NCS pose of the window's target frame (row 0 is zero); root (B, 3) NCS root; visible (B, F, J) False where a joint was dropped; cameras and
    world (B, J, 3): the cameras and the target frame's world joints, to go back to the world (they describe the scene before any flip).
    """

    pixels: np.ndarray
    rays: np.ndarray
    camera_params: np.ndarray
    pose: np.ndarray
    root: np.ndarray
    visible: np.ndarray
    cameras: CameraBatch
    world: np.ndarray


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


def body_frames(positions: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotations whose columns are each pose's body axes in the world: x from the right hip to the
    left hip (made horizontal), y forward, z up."""
    across = positions[..., H36M17.index("l_hip"), :] - positions[..., H36M17.index("r_hip"), :]
    across = across * np.array([1.0, 1.0, 0.0])
    across /= np.maximum(np.linalg.norm(across, axis=-1, keepdims=True), 1e-9)
    up = np.broadcast_to(np.array([0.0, 0.0, 1.0]), across.shape)
    return np.stack([across, np.cross(up, across), up], -1)


def offset_joints(windows: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(B, F, J, 3) world windows with each joint moved by (B, J, 3) ``offsets`` given in the body frame
    (``body_frames``), mirrored between left and right joints (x negated), the same in every frame."""
    offsets = offsets.copy()
    left = list(H36M17.left)
    offsets[:, left] = offsets[:, [H36M17.flip_permutation[i] for i in left]] * np.array([-1.0, 1.0, 1.0])
    offsets[:, [i for i in range(H36M17.num_joints) if i not in H36M17.left + H36M17.right], 0] = 0.0
    return windows + np.einsum("bfij,bkj->bfki", body_frames(windows), offsets)


def flip_batch(batch: Batch, mask: np.ndarray, skeleton: Skeleton = H36M17) -> Batch:
    """Mirror the samples where (B,) ``mask`` is True: the scene mirrored in the NCS (rays and targets) and its
    image about the principal point; (height, pitch) are unchanged. Flipping twice is the identity."""
    def where_masked(flipped: np.ndarray, original: np.ndarray) -> np.ndarray:
        out = original.copy()
        out[mask] = flipped
        return out

    cx = batch.cameras.intrinsics[mask, 2].astype(np.float32)
    return dataclasses.replace(
        batch, pixels=where_masked(mirror_pixels(batch.pixels[mask], cx[:, None, None], skeleton), batch.pixels),
        rays=where_masked(flip(batch.rays[mask], skeleton), batch.rays),
        pose=where_masked(flip(batch.pose[mask], skeleton), batch.pose),
        root=where_masked(batch.root[mask] * np.array([-1.0, 1.0, 1.0], dtype=np.float32), batch.root),
        visible=where_masked(batch.visible[mask][..., list(skeleton.flip_permutation)], batch.visible))


def observe(windows: np.ndarray, cameras: CameraBatch, window: Window, remove_roll: bool = False,
            rng: np.random.Generator | None = None, config: SampleConfig = SampleConfig()) -> Batch:
    """See (B, F, J, 3) world windows (F = ``window.frames``) through one camera each and build the network's
    inputs and the targets of the window's target frame.

    With ``rng`` None nothing random happens (evaluation); otherwise the 2D noise and dropped joints of
    ``config`` are applied (flip and bone scaling are the generator's). ``remove_roll`` selects the
    gravity-aligned NCS for the rays and targets.
    """
    count, frames, joints, _ = windows.shape
    if frames != window.frames:
        raise ValueError(f"observe: windows of {frames} frames for a {window.frames}-frame window")
    R, t = cameras.R[:, None, None], cameras.t[:, None, None]
    intrinsics, dist = cameras.intrinsics[:, None, None], cameras.dist[:, None, None]
    has_distortion = cameras.has_distortion
    points_camera = tf.world_to_camera(windows, R, t)
    pixels = tf.camera_to_pixels(points_camera, intrinsics, dist if has_distortion else None)
    rays_camera = points_camera / points_camera[..., 2:3]  # exact, no round trip through the lens
    visible = np.ones((count, frames, joints), dtype=bool)
    if rng is not None and config.drop_probability > 0:
        visible = rng.random(visible.shape) >= config.drop_probability
        visible[..., 0] = True  # the root has no parent to collapse onto
        parents = [max(p, 0) for p in H36M17.parents]
        pixels = np.where(visible[..., None], pixels, pixels[..., parents, :])
        rays_camera = np.where(visible[..., None], rays_camera, rays_camera[..., parents, :])
    if rng is not None and config.swap_probability > 0:
        swapped = rng.random((count, frames)) < config.swap_probability
        pixels = np.where(swapped[..., None, None], pixels[..., LEG_SWAP, :], pixels)
        rays_camera = np.where(swapped[..., None, None], rays_camera[..., LEG_SWAP, :], rays_camera)
    if rng is not None and config.noise_height_fraction[1] > 0:
        seen = pixels[:, window.target]
        span = np.nanmax(np.nanmax(seen, axis=1) - np.nanmin(seen, axis=1), axis=-1)  # (B,) the person's size
        sigma = config.noise_px + rng.uniform(*config.noise_height_fraction, count) * np.nan_to_num(span)
        pixels = pixels + rng.normal(0.0, 1.0, pixels.shape) * sigma[:, None, None, None]
    elif rng is not None and config.noise_px > 0:
        pixels = pixels + rng.normal(0.0, config.noise_px, pixels.shape)
    if rng is not None and (config.noise_px > 0 or config.noise_height_fraction[1] > 0):
        # The clean ray is a close start for undistorting the noisy pixel; where a wide lens cannot be
        # inverted there, the clean ray stays.
        noisy = tf.pixels_to_camera_rays(pixels, intrinsics, dist if has_distortion else None,
                                         initial_rays=rays_camera)
        rays_camera = np.where(np.isfinite(noisy), noisy, rays_camera)
    roll = cameras.roll if remove_roll else None
    rays = tf.rays_camera_to_normalized(rays_camera, cameras.pitch[:, None, None],
                                        None if roll is None else roll[:, None, None])
    index = window.target
    target = tf.camera_to_normalized(points_camera[:, index], cameras.height[:, None], cameras.pitch[:, None],
                                     None if roll is None else roll[:, None])
    return Batch(
        pixels=pixels.astype(np.float32), rays=rays.astype(np.float32),
        camera_params=cameras.height_pitch.astype(np.float32),
        pose=(target - target[:, :1]).astype(np.float32), root=target[:, 0].astype(np.float32),
        visible=visible, cameras=cameras, world=windows[:, index].astype(np.float32))


class SampleGenerator:
    """Random training batches from a motion set: uniform (clip, frame) draws, a random camera per sample,
    bone scaling, flips and detector-like 2D noise, all vectorised."""

    def __init__(self, motion: MotionSet, config: SampleConfig, window: Window, remove_roll: bool = False,
                 seed: int = 0):
        if motion.num_frames == 0:
            raise InputError("SampleGenerator: the motion set has no frames")
        self.motion, self.config, self.window, self.remove_roll = motion, config, window, remove_roll
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
        windows = scale_bones(windows, factors[:, None])
        if config.joint_offset_m > 0:
            windows = offset_joints(windows, rng.normal(0.0, config.joint_offset_m, (size, H36M17.num_joints, 3)))
        cameras = sample_cameras(windows[:, self.window.target, 0], rng, config.cameras)
        batch = observe(windows, cameras, self.window, self.remove_roll, rng, config)
        return flip_batch(batch, rng.random(size) < config.flip_probability)


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
