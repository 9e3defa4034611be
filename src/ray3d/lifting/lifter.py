"""``Lifter``: users' 2D keypoints and calibrated camera -> 3D joints in metres in the world frame.

Handles what real keypoints bring: other joint layouts (COCO-17, BlazePose-33, OpenPose BODY-25), missing joints
(NaN or confidence 0: interpolated in time and reported), other frame rates (resampled to the model's and back),
sequences shorter than the receptive field (edge-replicated), several people (each track lifted on its own into
one world frame), long sequences (in chunks), smoothing of the 2D input and 3D output, and a GPU when there is one.
"""

from __future__ import annotations

import dataclasses
import threading

import numpy as np
import torch

from ray3d import temporal
from ray3d.checkpoints import default_model, load_model
from ray3d.console import progress_bar
from ray3d.errors import InputError
from ray3d.geometry import Camera, CameraBatch
from ray3d.geometry.arrays import numeric_array
from ray3d.geometry.floor import FLAT_FLOOR, Floor
from ray3d.io.detections import TrackDetections
from ray3d.io.keypoints import Keypoints
from ray3d.io.world import LiftResult, World
from ray3d.lifting.floor_pass import lift_views
from ray3d.lifting.inputs import MODEL_FPS, PreparedTrack, camera_rays, prepare_track
from ray3d.lifting.options import LiftOptions
from ray3d.lifting.stream import LiftStream
from ray3d.lifting.tracks import CameraTracks, LiftedTracks, gathered, progress_labels
from ray3d.models.inference import BATCH_PER_GROUP, inference_network
from ray3d.models.network import LiftingNetwork, predict_world
from ray3d.models.precision import check_precision, with_precision
from ray3d.models.tensor_batch import TensorBatch
from ray3d.refine import RefineConfig
from ray3d.skeleton import Skeleton, conversion_matrix

SMALL_BATCHES_BEFORE_TRACING = 3


def _with_gaps(frames, keypoints: np.ndarray, confidences) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """``Lifter.lift``'s rows at ``frames``, their frame numbers -> (every frame number from the first to the last
    (T',), keypoints (T', J, 2) NaN and confidences (T', J) 0 in the frames skipped), as ``lift_tracks`` fills a
    track's gaps (``TrackDetections.dense``). Refused: frame numbers that are not one per row, not whole numbers,
    or not increasing."""
    numbers, rows = numeric_array(frames, "frames"), len(keypoints) if keypoints.ndim else 0
    if numbers.ndim != 1 or len(numbers) != rows:
        raise InputError(f"frames: the frame number of each of the keypoints' {rows} rows expected, got "
                         f"shape {numbers.shape}", arguments=("frames",))
    if not (np.isfinite(numbers).all() and (numbers == np.round(numbers)).all()):
        raise InputError("frames: whole numbers expected", arguments=("frames",))
    if (np.diff(numbers) <= 0).any():
        row = int(np.flatnonzero(np.diff(numbers) <= 0)[0]) + 1
        raise InputError(f"frames: frame numbers must increase row by row; row {row} has {numbers[row]:.0f} after "
                         f"{numbers[row - 1]:.0f}", arguments=("frames",))
    if confidences is not None:
        scores = numeric_array(confidences, "confidences")
        if scores.shape != keypoints.shape[:2]:
            raise InputError(f"confidences: expected shape {keypoints.shape[:-1]}, got {scores.shape}",
                             arguments=("confidences",))
    return TrackDetections(numbers, keypoints, confidences).dense("frames")


class Lifter:
    """A trained network ready to lift. ``Lifter.load()`` gives the shipped Ray3D weights."""

    def __init__(self, model, document: dict, device: str | torch.device | None = None, name: str | None = None):
        self.document = document
        self.name = name or model.config.name  # how world files name the model that lifted them
        if isinstance(model, LiftingNetwork):
            self.device = torch.device(device or ("cuda" if torch.cuda.is_available() else "cpu"))
            self.model = inference_network(model).to(self.device)
        else:  # the TorchScript, ONNX Runtime and reduced-precision backends run on the CPU
            self.device, self.model = torch.device("cpu"), model
        self.precision = getattr(model, "precision", "fp32")
        # Eager torch spends a small batch's time in Python dispatch (the lite model: 0.7-0.8 ms for one window
        # against 0.4-0.6 ms traced): a lifter that keeps being given small batches (a stream, live) runs them
        # through a frozen TorchScript trace of the same network, made once. Ray-input models only: a
        # pixel-input trace is bound to one image width.
        self._small_batches, self._small_batch_runner, self._tracing = 0, None, threading.Lock()
        self._traceable = (isinstance(self.model, LiftingNetwork) and self.device.type == "cpu"
                           and self.model.config.input.endswith("rays"))

    @classmethod
    def load(cls, name_or_path: str | None = None, device: str | None = None, backend: str = "torch",
             image_width: float = 1000.0, layout: str = "h36m17", precision: str = "fp32") -> Lifter:
        """A shipped model by name (``ray3d``, ``ray3d-real``, ``videopose3d``, ...) or a checkpoint path; without
        one, the shipped model for keypoints of ``layout`` (``checkpoints.default_model``: ``ray3d`` for H36M-17,
        ``ray3d-real`` for a detector's layout).

        ``backend="torchscript"`` runs a frozen TorchScript trace on the CPU (lowest latency with torch alone:
        live use); ``backend="onnx"`` runs it with ONNX Runtime (``pip install 'ray3d[onnx]'``). Pixel-input
        models are then built for images ``image_width`` pixels wide.

        ``precision="bf16"`` or ``"int8"`` runs the network's hidden matrix products in that precision on the
        CPU (``models.precision``; its accuracy cost is in docs/RESULTS.md and ``ray3d evaluate --precision``).
        """
        check_precision(precision)
        name_or_path = name_or_path or default_model(layout)
        model, document = load_model(name_or_path)
        if precision != "fp32":
            if backend != "torch" or (device or "cpu") != "cpu":
                raise InputError(f"precision {precision!r} runs on the torch backend on the CPU; got backend "
                                 f"{backend!r}, device {device or 'cpu'!r}")
            return cls(with_precision(model, precision), document, name=str(name_or_path))
        if backend in ("torchscript", "onnx"):
            from ray3d.models import backends

            runner = (backends.TorchScriptLiftingModel(model, image_width) if backend == "torchscript"
                      else backends.OnnxLiftingModel(model, image_width))
            return cls(runner, document, name=str(name_or_path))
        if backend != "torch":
            raise InputError(f"unknown backend {backend!r}; 'torch', 'torchscript' or 'onnx'")
        return cls(model, document, device=device, name=str(name_or_path))

    @property
    def receptive_field(self) -> int:
        return self.model.receptive_field

    def lift(self, keypoints, camera: Camera, confidences=None, fps: float | None = None, layout: str = "h36m17",
             smooth_2d: str | None = None, smooth_3d: str | None = None, flip_test: bool = False,
             chunk: int = 8192, refine: bool | RefineConfig = True, progress: bool | str = False,
             floor: Floor = FLAT_FLOOR, floor_z: float | None = None,
             frames=None) -> LiftResult | list[LiftResult]:
        """Lift one person's pixels (T, J, 2) seen by ``camera``; (B, T, J, 2) lifts B sequences.

        Args:
            keypoints: pixels (u, v) in ``layout`` (h36m17, coco17, blazepose33, body25, ...); NaN = missing.
            confidences: optional (T, J) scores (0: missing); fps: the input's frame rate (default: the model's, 60).
            smooth_2d / smooth_3d: ``"savgol"`` or ``"one-euro"`` on the input pixels / output joints.
            refine: move the person along their rays so the feet rest on the ``floor``, one body size (``ray3d.refine``;
                a ``RefineConfig`` sets its uncertainties); False keeps the network's (either has its uncertainty).
            floor_z: where the floor people stand on lies in the camera's frame (0: at its z = 0); None decides it
                on what the person shows against the camera's z = 0 (``ray3d.refine.ankle_plane``; ``lift_tracks``
                decides it on everybody). Refined, ``result.refinement["ankle_plane"]`` says what was decided.
            progress: a progress bar over the frames (a string labels it) for sequences longer than a chunk.
            frames: optional (T,) frame number of each row (increasing whole numbers; (B, T) for B sequences):
                frames the rows skip are filled in like missing joints, as ``lift_tracks`` fills a track's gaps,
                and ``result.frames`` are the frame numbers from the first row's to the last's. Without it the rows
                are taken as consecutive frames and ``result.frames`` counts them from 0.
        """
        keypoints = numeric_array(keypoints, "keypoints")
        if keypoints.ndim == 4:
            scores = [None] * len(keypoints) if confidences is None else confidences
            numbers = [None] * len(keypoints) if frames is None else numeric_array(frames, "frames")
            if frames is not None and (numbers.ndim != 2 or len(numbers) != len(keypoints)):
                raise InputError(f"frames: the (B, T) frame numbers of {len(keypoints)} sequences of keypoints "
                                 f"expected, got shape {numbers.shape}", arguments=("frames",))
            return [self.lift(k, camera, c, fps, layout, smooth_2d, smooth_3d, flip_test, chunk, refine, progress,
                              floor, floor_z, f) for k, c, f in zip(keypoints, scores, numbers)]
        span = None
        if frames is not None:
            span, keypoints, confidences = _with_gaps(frames, keypoints, confidences)
        options = LiftOptions(smooth_2d, smooth_3d, flip_test, refine, floor=floor, floor_z=floor_z)
        view = CameraTracks({0: self._prepare(keypoints, camera, confidences, fps, layout, options.smooth_2d)}, camera,
                            {0: progress}, options)
        (lifted,), _ = lift_views(self, [view], chunk)
        if isinstance(lifted[0], InputError):
            raise lifted[0]
        return lifted[0] if span is None else dataclasses.replace(lifted[0], frames=span)

    def _prepare(self, keypoints: np.ndarray, camera: Camera, confidences, fps: float | None, layout: str,
                 smooth_2d: str | None) -> PreparedTrack:
        return prepare_track(keypoints, camera, confidences, fps, layout, smooth_2d, self.input_skeleton)

    def network(self, prepared: PreparedTrack, camera: Camera, flip_test: bool, chunk: int,
                progress: bool | str) -> np.ndarray:
        """(T, 17, 3) world joints of a prepared track as the network puts them (``floor_pass`` runs it)."""
        fps, pixels, scores = prepared.fps, prepared.pixels, prepared.scores
        resampled = temporal.needs_resampling(fps, MODEL_FPS)
        if resampled:
            pixels, scores = temporal.resample(pixels, fps, MODEL_FPS), temporal.resample(scores, fps, MODEL_FPS)
        joints = self._lift_pixels(pixels, camera, flip_test, chunk, progress, scores)
        return temporal.resample_back(joints, MODEL_FPS, fps, len(prepared.pixels)) if resampled else joints

    def input_skeleton(self, skeleton: Skeleton) -> Skeleton:
        """The model's input layout, after checking that keypoints of ``skeleton`` give its joints."""
        inputs = self.model.config.input_skeleton
        try:
            conversion_matrix(skeleton.name, inputs.name)
        except InputError:
            raise InputError(f"keypoints: model {self.name} reads {inputs.name} joints, which {skeleton.name} "
                             "keypoints do not have; lift them with a model of H36M-17 input such as ray3d",
                             arguments=("checkpoint",)) from None
        return inputs

    def lift_tracks(self, tracks: dict, camera: Camera, layout: str = "h36m17", fps: float | None = None,
                    progress: bool = False, smooth_2d: str | None = None, smooth_3d: str | None = None,
                    flip_test: bool = False, chunk: int = 8192, refine: bool | RefineConfig = True,
                    floor: Floor = FLAT_FLOOR, floor_z: float | None = None, seen_before: tuple = ()) -> LiftedTracks:
        """Several people: {track id: ``TrackDetections`` or (frame indices (N,), keypoints (N, J, 2)[,
        confidences (N, J)])} -> {track id: LiftResult} in one world frame; the options as for ``lift``. Frames a
        track skips are filled in like missing joints (each result's ``frames``: its track's first to its last).
        What the tracks share, where their ankles meet the floor, is decided on what all of them show together
        (``LiftedTracks.ankle_plane``, and each result's ``refinement["ankle_plane"]``) and what people the camera
        saw before showed (``seen_before``: the ``SizeEvidence`` and ``SeenTwice`` of earlier lifts'
        ``LiftedTracks.floor_evidence()``; live and the floor's memory keep them), unless ``floor_z`` gives it. A
        track that cannot be lifted (say, its root never seen) is left out and named in the result's
        ``unliftable`` with why; only when no track can be lifted is that an error."""
        options = LiftOptions(smooth_2d, smooth_3d, flip_test, refine, floor=floor, floor_z=floor_z,
                              seen_before=seen_before)
        prepared, spans, failures = self._prepare_tracks(tracks, camera, fps, layout, options.smooth_2d)
        view = CameraTracks(prepared, camera, progress_labels(prepared, progress), options)
        (lifted,), (plane,) = lift_views(self, [view], chunk)
        return gathered(LiftedTracks(view.found, view.ankles), tracks, lifted, spans, failures, plane)

    def lift_cameras(self, views: dict, layout: str | dict = "h36m17", fps: float | dict | None = None,
                     progress: bool = False, smooth_2d: str | None | dict = None, smooth_3d: str | None | dict = None,
                     flip_test: bool | dict = False, chunk: int = 8192, refine: bool | RefineConfig = True,
                     floor: Floor | dict = FLAT_FLOOR, floor_z: float | None | dict = None,
                     one_clock: bool = True, seen_before: tuple | dict = ()) -> dict:
        """Several cameras of one site, in one world frame on one floor: {view: (tracks as ``lift_tracks`` takes
        them, its Camera)} -> {view: LiftedTracks}. Where that floor lies is observed from every camera's people
        together (each camera's tracks tell it from that camera's height, its keypoints at their detector's
        height) and, where the views' frame ids are ``one_clock`` and two cameras see a person at once, from their
        ankles triangulated; a floor given (``floor_z``) is the site's, the same for every view that gives one. A
        view none of whose tracks could be lifted maps to the InputError saying why. ``layout``, ``fps``,
        ``smooth_2d``, ``smooth_3d``, ``flip_test``, ``floor``, ``floor_z`` and ``seen_before`` (what each camera's
        people showed of the floor before, as ``lift_tracks`` takes it) may be {view: value}: each camera is
        lifted with its own."""
        def own(value, name):
            return value[name] if isinstance(value, dict) else value

        passes = {}
        for name, (tracks, camera) in views.items():
            options = LiftOptions(own(smooth_2d, name), own(smooth_3d, name), own(flip_test, name), refine,
                                  floor=own(floor, name), floor_z=own(floor_z, name),
                                  seen_before=own(seen_before, name))
            prepared, spans, failures = self._prepare_tracks(tracks, camera, own(fps, name), own(layout, name),
                                                             options.smooth_2d)
            view = CameraTracks(prepared, camera, progress_labels(prepared, progress), options)
            passes[name] = (tracks, spans, failures, view)
        lifted, planes = lift_views(self, [view for *_, view in passes.values()], chunk,
                                    spans=[spans for _, spans, _, _ in passes.values()] if one_clock else None)
        out = {}
        for (name, (tracks, spans, failures, view)), outcome, plane in zip(passes.items(), lifted, planes):
            try:
                out[name] = gathered(LiftedTracks(view.found, view.ankles), tracks, outcome, spans, failures, plane)
            except InputError as err:
                out[name] = err
        return out

    def _prepare_tracks(self, tracks: dict, camera: Camera, fps: float | None, layout: str,
                        smooth_2d: str | None) -> tuple[dict, dict, dict]:
        """{track: detections} -> {track: PreparedTrack}, {track: its frame span}, {track: the InputError refusing
        it}."""
        prepared, spans, failures = {}, {}, {}
        for track, entry in tracks.items():
            try:
                if not isinstance(entry, tuple) or len(entry) not in (2, 3):
                    raise InputError(f"tracks[{track!r}]: expected (frame ids, pixels[, confidences])", ("tracks",))
                spans[track], pixels, confidences = TrackDetections(*entry).dense(f"tracks[{track!r}]")
                prepared[track] = self._prepare(pixels, camera, confidences, fps, layout, smooth_2d)
            except InputError as err:
                failures[track] = err
        return prepared, spans, failures

    def lift_keypoints(self, keypoints: Keypoints, camera: Camera, options: LiftOptions = LiftOptions(),
                       progress: bool = False) -> World:
        """Every track of a keypoint file (``ray3d.io.keypoints.read_keypoints``) lifted into one world frame
        (the frame ``options`` name); tracks that cannot be lifted are named in ``World.unliftable``."""
        try:
            tracks = self.lift_tracks(keypoints.by_track(), camera, keypoints.layout, keypoints.fps, progress,
                                      **options.lift_arguments())
        except InputError as err:  # name the file the keypoints came from
            raise InputError(f"{keypoints.path or keypoints.source}: {err.message}", err.arguments) from None
        return World(tracks, camera, self.name, unliftable=tracks.unliftable,
                     floor_evidence=tracks.floor_evidence()).in_frame(options.frame)

    @torch.no_grad()
    def _lift_pixels(self, pixels: np.ndarray, camera: Camera, flip_test: bool, chunk: int,
                     progress: bool | str = False, confidences: np.ndarray | None = None) -> np.ndarray:
        """(T, J, 2) pixels of the model's input layout (gaps filled) and their (T, J) confidences -> (T, 17, 3)
        world joints."""
        rays = camera_rays(camera, pixels, self.model.config.remove_roll)
        count = len(pixels)
        # Windows are gathered chunk by chunk (never all at once), which keeps memory bounded.
        index = temporal.sequence_window_indices(count, self.model.config.window)
        out = np.empty((count, 17, 3))
        bar = progress_bar(total=count, unit="frame", desc=progress if isinstance(progress, str) else "lifting",
                           shown=bool(progress) and count > chunk)
        for start in range(0, count, chunk):
            part = index[start:start + chunk]
            out[start:start + len(part)] = self.lift_windows(pixels[part], rays[part], camera, flip_test,
                                                              None if confidences is None else confidences[part])
            bar.update(len(part))
        bar.close()
        return out

    @torch.no_grad()
    def lift_windows(self, pixels: np.ndarray, rays: np.ndarray, camera: Camera, flip_test: bool,
                     confidences: np.ndarray | None = None) -> np.ndarray:
        """(N, F, J, 2) pixel, (N, F, J, 3) ray and optional (N, F, J) confidence windows of the model's input
        layout seen by ``camera`` -> (N, 17, 3) world joints."""
        cameras = CameraBatch.repeated(camera, len(pixels))
        batch = TensorBatch.from_arrays(pixels, rays, cameras, self.device, confidences)
        return predict_world(self._runner(len(pixels)), batch, cameras, flip_test).cpu().numpy()

    def _runner(self, windows: int):
        """What runs a batch of ``windows``: the network, or from the third small batch (below
        ``BATCH_PER_GROUP`` windows) on, its TorchScript trace."""
        if not self._traceable or windows >= BATCH_PER_GROUP:
            return self.model
        if self._small_batch_runner is None:
            self._small_batches += 1
            if self._small_batches >= SMALL_BATCHES_BEFORE_TRACING:
                self._trace_small_batches()
        return self._small_batch_runner or self.model

    def prepare_small_batches(self) -> None:
        """Make the small-batch trace now (about 0.2 s, holding the interpreter: a thread would not hide it)
        rather than on the third small batch: for a caller about to send small batches on a clock (``ray3d
        live``), before its frames flow."""
        self._trace_small_batches()

    def _trace_small_batches(self) -> None:
        # Not waiting for a trace another thread is making: meanwhile its small batches run the network itself.
        if not self._traceable or not self._tracing.acquire(blocking=False):
            return
        try:
            if self._small_batch_runner is None:
                from ray3d.models.backends import TorchScriptLiftingModel

                self._small_batch_runner = TorchScriptLiftingModel(self.model, batches=(2,))
        finally:
            self._tracing.release()

    def stream(self, camera: Camera, layout: str = "h36m17", flip_test: bool = False, fps: float | None = None,
               wait_for_future: bool = True) -> LiftStream:
        """Lift frame by frame as keypoints arrive (live use); see ``LiftStream``."""
        return LiftStream(self, camera, layout, flip_test, fps, wait_for_future)
