"""``LiftStream``: lifting one person frame by frame as their keypoints arrive (live use), and ``lift_streams``:
one network call for every stream that has a new frame."""

from __future__ import annotations

import numpy as np

from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.lifting.inputs import MODEL_FPS, camera_rays, checked_keypoints, model_inputs, stand_in_for_unseen
from ray3d.lifting.runner import ModelRunner
from ray3d.skeleton import layout_skeleton


class LiftStream:
    """Live lifting: ``push`` one frame's keypoints (J, 2) and get world joints (17, 3) back, from a model's
    ``runner`` (``Lifter.stream`` makes one).

    ``fps`` is the input's frame rate (default: the model's, 60). Frames at another rate are brought to the
    model's as offline lifting does, by linear interpolation in time, causally: each frame adds the model-rate
    frames since the one before it, and the answer is for the last of them (the frame itself when the rates divide).

    A causal model (``ModelConfig.causal``, e.g. ``ray3d-causal``) answers for the frame just pushed. A centred
    model needs ``delay`` (half its window) model-rate frames of the future. With ``wait_for_future`` it answers
    for the frame pushed that much earlier (None until then) and ``flush()`` gives the last frames when the
    stream ends: the outputs then equal ``Lifter.lift`` on the whole sequence to float rounding (no smoothing, no
    refinement, which needs the whole track). Without it, it answers at once with the future stood in by the
    present frame, as offline lifting does at a sequence's end: never later than the frame, a little less sure.

    A joint missing from a frame (NaN or confidence 0) keeps its last seen position (with confidence 0); one
    not seen yet takes its parent's, as a detector's miss is simulated in training.
    """

    def __init__(self, runner: ModelRunner, camera: Camera, layout: str = "h36m17", flip_test: bool = False,
                 fps: float | None = None, wait_for_future: bool = True):
        config = runner.model.config
        self.runner, self.camera, self.skeleton, self.flip_test = runner, camera, layout_skeleton(layout), flip_test
        self.frames = runner.receptive_field
        self.delay = config.window.delay if wait_for_future else 0
        self.lookahead = config.window.delay - self.delay  # future frames stood in by the present
        self.step = MODEL_FPS / (fps or MODEL_FPS)      # model-rate frames per input frame
        if self.delay and abs(self.step - 1) > 1e-3:
            raise InputError(f"fps: a centred model waits for future frames only at its own {MODEL_FPS:g} frames/s; "
                             "stream without waiting for them", arguments=("wait_for_future",))
        self.remove_roll = config.remove_roll
        self.inputs = runner.input_skeleton(self.skeleton)  # the joints the model reads
        self._pixels: np.ndarray | None = None   # (F, J, 2) the current window, of the model's input layout
        self._rays: np.ndarray | None = None     # (F, J, 3)
        self._scores: np.ndarray | None = None   # (F, J) confidences
        self._last_seen = np.full((self.inputs.num_joints, 2), np.nan)
        self._model_frames = 0  # model-rate frames made so far
        self._time = 0          # the last frame pushed, in input frames after the first
        self.pushed = 0       # frames pushed so far
        self.answered = 0     # frames answered so far

    def push(self, keypoints, confidences=None, frames_since_last: int = 1) -> np.ndarray | None:
        """One frame's pixels (J, 2) in the stream's layout -> world joints (17, 3) of frame ``answered``
        (the frame just pushed for a causal model, or without waiting), or None while a centred model waits
        for future frames; ``frames_since_last`` as ``add``'s."""
        self.add(keypoints, confidences, frames_since_last)
        return lift_streams([self])[0] if self.ready() else None

    def add(self, keypoints, confidences=None, frames_since_last: int = 1) -> None:
        """Take one frame's pixels (J, 2) without answering (``lift_streams`` answers several streams at once);
        ``frames_since_last``: input frames since the one pushed before (more than 1 where frames were skipped or
        the person was not seen: the model still reads them at their true times)."""
        if frames_since_last < 1 or (frames_since_last != 1 and self.delay):
            raise InputError(f"frames_since_last: {frames_since_last}; frames come in order, and a stream waiting for "
                             "the future takes every frame", arguments=("frames_since_last",))
        pixels, scores = self._prepare(keypoints, confidences)
        if self._pixels is None:
            self._append(pixels[None], scores[None])
            self._model_frames, self._time = 1, 0
        else:
            # The model-rate frames after the last one made, up to this frame's time, interpolated in time.
            before = self._time * self.step
            self._time += int(frames_since_last)
            until = int(np.floor(self._time * self.step + 1e-6)) + 1
            shares = (np.arange(self._model_frames, until) - before) / (self._time * self.step - before)
            if len(shares):
                self._append(self._pixels[-1] + shares[:, None, None] * (pixels - self._pixels[-1]),
                             self._scores[-1] + shares[:, None] * (scores - self._scores[-1]))
            self._model_frames = max(until, self._model_frames)
        self.pushed += 1

    def ready(self) -> bool:
        """Whether the stream can answer for a frame it has not answered yet."""
        return self.pushed > self.answered + self.delay

    def flush(self) -> list[np.ndarray]:
        """The frames still unanswered at the end of the stream (none for a causal model or without waiting)."""
        answers, window_end = [], self.pushed - 1  # the frame the window ends at (waiting is at the model's rate)
        while self.answered < self.pushed:
            while window_end < self.answered + self.delay:
                self._append(self._pixels[-1:], self._scores[-1:])
                window_end += 1
            answers.append(lift_streams([self])[0])
        return answers

    def window(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The (F, J, 2) pixels, (F, J, 3) rays and (F, J) confidences the next answer reads: with the future
        stood in by the present when not waiting for it."""
        if not self.lookahead:
            return self._pixels, self._rays, self._scores
        return tuple(np.concatenate([a[self.lookahead:], np.repeat(a[-1:], self.lookahead, axis=0)])
                     for a in (self._pixels, self._rays, self._scores))

    def _prepare(self, keypoints, confidences) -> tuple[np.ndarray, np.ndarray]:
        keypoints, confidences = checked_keypoints(keypoints, confidences, self.skeleton)
        pixels, seen, scores = model_inputs(keypoints, self.skeleton, confidences, self.inputs)
        self._last_seen = np.where(seen[:, None], pixels, self._last_seen)
        filled = stand_in_for_unseen(self._last_seen[None], np.isnan(self._last_seen).any(axis=-1), self.inputs)[0]
        return filled, scores

    def _append(self, pixels: np.ndarray, scores: np.ndarray) -> None:
        """Model-rate frames (K, J, 2) and their confidences (K, J) onto the window's end."""
        rays = camera_rays(self.camera, pixels, self.remove_roll)
        if self._pixels is None:
            self._pixels = np.repeat(pixels[-1:], self.frames, axis=0)
            self._rays = np.repeat(rays[-1:], self.frames, axis=0)
            self._scores = np.repeat(scores[-1:], self.frames, axis=0)
        else:
            self._pixels = np.concatenate([self._pixels, pixels])[-self.frames:]
            self._rays = np.concatenate([self._rays, rays])[-self.frames:]
            self._scores = np.concatenate([self._scores, scores])[-self.frames:]


def lift_streams(streams: list[LiftStream]) -> list[np.ndarray]:
    """One answer (17, 3) for each of ``streams`` (of one runner and camera, each ``ready()``) from a single
    call of the network."""
    if not streams:
        return []
    first = streams[0]
    pixels, rays, scores = (np.stack(parts) for parts in zip(*(stream.window() for stream in streams)))
    answers = first.runner.lift_windows(pixels, rays, first.camera, first.flip_test, scores)
    for stream in streams:
        stream.answered += 1
    return list(answers)
