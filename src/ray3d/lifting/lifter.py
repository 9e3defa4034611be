"""``Lifter``: users' 2D keypoints and calibrated camera -> 3D joints in metres in the world frame.

Handles what real keypoints bring: other joint layouts (COCO-17, BlazePose-33, OpenPose BODY-25), missing joints
(NaN or confidence 0: interpolated in time and reported), other frame rates (resampled to the model's and back),
sequences shorter than the receptive field (edge-replicated), several people (each track lifted on its own into
one world frame), long sequences (in chunks), smoothing of the 2D input and 3D output, and a GPU when there is one.
"""

from __future__ import annotations

import dataclasses

from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.geometry.arrays import numeric_array
from ray3d.geometry.floor import FLAT_FLOOR, Floor
from ray3d.io.keypoints import Keypoints
from ray3d.io.world import LiftResult, World
from ray3d.lifting.floor_pass import lift_views
from ray3d.lifting.inputs import prepare_track
from ray3d.lifting.options import LiftOptions
from ray3d.lifting.runner import ModelRunner
from ray3d.lifting.stream import LiftStream
from ray3d.lifting.tracks import CameraTracks, LiftedTracks, gathered, prepared_tracks, progress_labels, rows_with_gaps
from ray3d.refine import RefineConfig
from ray3d.skeleton import Skeleton


class Lifter:
    """Users' keypoints and a calibrated camera -> world joints, by a trained network (its ``runner``, a
    ``ModelRunner``). ``Lifter.load()`` gives the shipped Ray3D weights."""

    def __init__(self, model, document: dict | None = None, device: str | None = None, name: str | None = None):
        """A network (or a backend's) with the ``document`` saved beside its weights, on ``device`` (default: a GPU
        where there is one), named ``name`` in world files (default: its config's); or a ``ModelRunner``."""
        self.runner = model if isinstance(model, ModelRunner) else ModelRunner(model, document or {}, device, name)

    @classmethod
    def load(cls, name_or_path: str | None = None, device: str | None = None, backend: str = "torch",
             image_width: float = 1000.0, layout: str = "h36m17", precision: str = "fp32") -> Lifter:
        """The model ``ModelRunner.load`` gives (the shipped one for keypoints of ``layout`` without a name or
        path), run by ``backend`` on ``device`` in ``precision``."""
        return cls(ModelRunner.load(name_or_path, device, backend, image_width, layout, precision))

    # What callers read of the model, from its runner.
    name = property(lambda self: self.runner.name)  # how world files name the model that lifted them
    document = property(lambda self: self.runner.document)
    model = property(lambda self: self.runner.model)
    receptive_field = property(lambda self: self.runner.receptive_field)

    def input_skeleton(self, skeleton: Skeleton) -> Skeleton:
        return self.runner.input_skeleton(skeleton)

    def prepare_small_batches(self) -> None:
        self.runner.prepare_small_batches()

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
            span, keypoints, confidences = rows_with_gaps(frames, keypoints, confidences)
        options = LiftOptions(smooth_2d, smooth_3d, flip_test, refine, floor=floor, floor_z=floor_z)
        prepared = prepare_track(keypoints, camera, confidences, fps, layout, options.smooth_2d, self.input_skeleton)
        (lifted,), _ = lift_views(self.runner, [CameraTracks({0: prepared}, camera, {0: progress}, options)], chunk)
        if isinstance(lifted[0], InputError):
            raise lifted[0]
        return lifted[0] if span is None else dataclasses.replace(lifted[0], frames=span)

    def lift_tracks(self, tracks: dict, camera: Camera, layout: str = "h36m17", fps: float | None = None,
                    progress: bool = False, smooth_2d: str | None = None, smooth_3d: str | None = None,
                    flip_test: bool = False, chunk: int = 8192, refine: bool | RefineConfig = True,
                    floor: Floor = FLAT_FLOOR, floor_z: float | None = None, seen_before: tuple = (),
                    options: LiftOptions | None = None) -> LiftedTracks:
        """Several people: {track id: ``TrackDetections`` or (frame indices (N,), keypoints (N, J, 2)[,
        confidences (N, J)])} -> {track id: LiftResult} in one world frame; the options as for ``lift`` (or a
        ``LiftOptions``, ``options``): ``lift_cameras`` with one camera. Frames a
        track skips are filled in like missing joints (each result's ``frames``: its track's first to its last).
        What the tracks share, where their ankles meet the floor, is decided on what all of them show together
        (``LiftedTracks.ankle_plane``, and each result's ``refinement["ankle_plane"]``) and what people the camera
        saw before showed (``seen_before``: the ``SizeEvidence`` and ``SeenTwice`` of earlier lifts'
        ``LiftedTracks.floor_evidence()``; live and the floor's memory keep them), unless ``floor_z`` gives it. A
        track that cannot be lifted (say, its root never seen) is left out and named in the result's
        ``unliftable`` with why; only when no track can be lifted is that an error."""
        lifted = self.lift_cameras({0: (tracks, camera)}, layout, fps, progress, smooth_2d, smooth_3d, flip_test, chunk,
                                   refine, floor, floor_z, seen_before=seen_before, options=options)[0]
        if isinstance(lifted, InputError):
            raise lifted
        return lifted

    def lift_cameras(self, views: dict, layout: str | dict = "h36m17", fps: float | dict | None = None,
                     progress: bool = False, smooth_2d: str | None | dict = None, smooth_3d: str | None | dict = None,
                     flip_test: bool | dict = False, chunk: int = 8192, refine: bool | RefineConfig = True,
                     floor: Floor | dict = FLAT_FLOOR, floor_z: float | None | dict = None,
                     one_clock: bool = True, seen_before: tuple | dict = (),
                     options: LiftOptions | dict | None = None) -> dict:
        """Several cameras of one site, in one world frame on one floor: {view: (tracks as ``lift_tracks`` takes
        them, its Camera)} -> {view: LiftedTracks}. Where that floor lies is observed from every camera's people
        together (each camera's tracks tell it from that camera's height, its keypoints at their detector's
        height) and, where the views' frame ids are ``one_clock`` and two cameras see a person at once, from their
        ankles triangulated; a floor given (``floor_z``) is the site's, the same for every view that gives one. A
        view none of whose tracks could be lifted maps to the InputError saying why. ``layout``, ``fps``,
        ``smooth_2d``, ``smooth_3d``, ``flip_test``, ``floor``, ``floor_z`` and ``seen_before`` (what each camera's
        people showed of the floor before, as ``lift_tracks`` takes it) may be {view: value}: each camera is
        lifted with its own. ``options`` (a ``LiftOptions``, or {view: its own}) stands in place of the keyword
        options from ``smooth_2d`` to ``seen_before`` (the views are refined as the first view's options say)."""
        def own(value, name):
            return value[name] if isinstance(value, dict) else value

        if options is None:
            options = {name: LiftOptions(own(smooth_2d, name), own(smooth_3d, name), own(flip_test, name), refine,
                                         floor=own(floor, name), floor_z=own(floor_z, name),
                                         seen_before=own(seen_before, name)) for name in views}
        passes = {}
        for name, (tracks, camera) in views.items():
            prepared, spans, failures = prepared_tracks(tracks, camera, own(fps, name), own(layout, name),
                                                        own(options, name).smooth_2d, self.input_skeleton)
            passes[name] = (tracks, spans, failures,
                            CameraTracks(prepared, camera, progress_labels(prepared, progress), own(options, name)))
        lifted, planes = lift_views(self.runner, [view for *_, view in passes.values()], chunk,
                                    spans=[spans for _, spans, _, _ in passes.values()] if one_clock else None)
        out = {}
        for (name, (tracks, spans, failures, view)), outcome, plane in zip(passes.items(), lifted, planes):
            try:
                out[name] = gathered(LiftedTracks(view.found, view.ankles), tracks, outcome, spans, failures, plane)
            except InputError as err:
                out[name] = err
        return out

    def lift_keypoints(self, keypoints: Keypoints, camera: Camera, options: LiftOptions = LiftOptions(),
                       progress: bool = False) -> World:
        """Every track of a keypoint file (``ray3d.io.keypoints.read_keypoints``) lifted into one world frame
        (the frame ``options`` name); tracks that cannot be lifted are named in ``World.unliftable``."""
        try:
            tracks = self.lift_tracks(keypoints.by_track(), camera, keypoints.layout, keypoints.fps, progress,
                                      options=options)
        except InputError as err:  # name the file the keypoints came from
            raise InputError(f"{keypoints.path or keypoints.source}: {err.message}", err.arguments) from None
        return World(tracks, camera, self.name, unliftable=tracks.unliftable,
                     floor_evidence=tracks.floor_evidence()).in_frame(options.frame)

    def stream(self, camera: Camera, layout: str = "h36m17", flip_test: bool = False, fps: float | None = None,
               wait_for_future: bool = True) -> LiftStream:
        """Lift frame by frame as keypoints arrive (live use); see ``LiftStream``."""
        return LiftStream(self.runner, camera, layout, flip_test, fps, wait_for_future)
