"""One camera's tracks on the first camera's clock (``on_clock``), and what comparing two of them needs: floor
velocities, and the distance and gate that say whether two cameras' tracks can be one person (``pair_distance``);
the root's ray-shaped uncertainty is the record's own (``geometry.uncertainty.Positioned``)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ray3d.geometry.uncertainty import Positioned
from ray3d.io.world import World
from ray3d.temporal import velocity

GATE_SIGMAS = 3.0     # how many (combined) standard deviations two cameras' places of one person may differ
GATE_FLOOR_M = 0.25   # plus this: a body is not a point (the pelvis seen from two sides)
MIN_SHARED_FRAMES = 5
VELOCITY_GATE_M_S = 0.6  # one person's floor velocity as two cameras see it differs by less (median)


@dataclasses.dataclass
class CameraTrack(Positioned):
    """One camera's track read on the first camera's frames: which camera (``view``), its name there, the joints
    in the world, the root's sd along and across its ray, the joints filled in (not seen) and the stature."""

    view: int
    name: str
    frames: np.ndarray      # (N,) the first camera's frames it covers
    joints: np.ndarray      # (N, 17, 3)
    position_sd: np.ndarray  # (N, 2) root sd along and across the ray (NaN where the track states none)
    interpolated: np.ndarray  # (N, 17)
    stature_m: float | None

    def at(self, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The rows of ``frames`` this track has, and those frames' positions in it."""
        shared, rows, _ = np.intersect1d(self.frames, frames, return_indices=True)
        return shared, rows


def on_clock(world: World, view: int, offset_s: float, fps: float) -> list[CameraTrack]:
    """A camera's tracks read on the first camera's frames (linear in time; within each track's span)."""
    tracks = []
    for name, result in world.in_frame("world").tracks.items():
        times = result.frames / result.fps - offset_s
        frames = np.arange(np.ceil(times[0] * fps - 1e-6), np.floor(times[-1] * fps + 1e-6) + 1).astype(int)
        frames = frames[frames >= 0]  # before the first camera's clock starts: not on it
        if not len(frames):
            continue
        at = frames / fps

        def read(values: np.ndarray) -> np.ndarray:
            flat = values.reshape(len(values), -1).astype(np.float64)
            return np.stack([np.interp(at, times, column) for column in flat.T], axis=-1).reshape(
                (len(at),) + values.shape[1:])

        sd = result.position_sd if result.position_sd is not None else np.full((len(times), 2), np.nan)
        stature = (result.refinement or {}).get("stature_m")
        tracks.append(CameraTrack(view, name, frames, read(result.joints), read(sd), read(result.interpolated) > 0.5,
                             None if stature is None else float(stature)))
    return tracks




def floor_velocity(track: CameraTrack, rows: np.ndarray, fps: float) -> np.ndarray:
    """(N, 2) the floor velocity at ``rows``, over half a second each side (m/s)."""
    return velocity(track.frames / fps, track.joints[:, 0, :2], 0.5, 0.5)[0][rows]


def pair_distance(a: CameraTrack, b: CameraTrack, fps: float = 10.0) -> tuple[float, float, int]:
    """Median floor distance between two tracks over their shared frames, the gate for it (infinitely far where
    they walk differently: two people passing close by), the frames shared."""
    shared, rows_a, rows_b = np.intersect1d(a.frames, b.frames, return_indices=True)
    if len(shared) < MIN_SHARED_FRAMES:
        return np.inf, 0.0, len(shared)
    gap = np.linalg.norm(a.joints[rows_a, 0, :2] - b.joints[rows_b, 0, :2], axis=-1)
    larger_a, larger_b = a.stated_sd(rows_a).max(axis=-1), b.stated_sd(rows_b).max(axis=-1)
    allowed = gate_m(larger_a, larger_b)
    pace = np.linalg.norm(floor_velocity(a, rows_a, fps) - floor_velocity(b, rows_b, fps), axis=-1)
    if np.median(pace) > VELOCITY_GATE_M_S:
        return np.inf, float(np.median(allowed)), len(shared)
    return float(np.median(gap)), float(np.median(allowed)), len(shared)






def handover_reach_m(gap_s: float) -> float:
    """How far from where a person's walk would have taken them a track starting ``gap_s`` after theirs ended
    may start and still be them (a hand-over between views, or a track broken where a camera lost them)."""
    return GATE_FLOOR_M + 0.5 * gap_s + 0.3


def gate_m(sd_a, sd_b):
    """How far apart two cameras' places of one person may be, given each place's largest sd (arrays alike)."""
    return GATE_SIGMAS * np.hypot(sd_a, sd_b) + GATE_FLOOR_M

