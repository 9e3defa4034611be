"""A job, as the user asked for it: its inputs (keypoint files or videos, one per camera), each input's camera,
the detector, the model, how people are lifted and followed, and what is written. Built from the command line's
arguments or from a batch manifest's row; checked when it is made, so a bad option is refused before any work."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from ray3d.errors import InputError
from ray3d.geometry import Camera
from ray3d.io.camera_files import camera_from_options, floor_of_camera_file, floor_z_of_camera_file, read_floor
from ray3d.io.world import WRITTEN_FORMATS
from ray3d.lifting.options import LiftOptions, VideoOptions
from ray3d.models.precision import check_precision

VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg", ".wmv")


def input_kind(path: str | Path) -> str:
    """"video" or "keypoints", by the file's suffix."""
    return "video" if Path(path).suffix.lower() in VIDEO_SUFFIXES else "keypoints"


@dataclasses.dataclass(frozen=True)
class CameraChoice:
    """How one input's camera is given: a camera file (ours, OpenCV's, ``FILE.toml:NAME``, ``h36m:SUBJECT:ID``),
    or its ``camera_height`` (m), ``pitch`` and ``roll`` (degrees) and lens (``hfov`` degrees or ``focal`` pixels)
    for images ``image_size`` (a video's own unless given), or a ``Camera`` already made."""

    file: str | None = None
    camera_height: float | None = None
    pitch: float | None = None
    image_size: Any = None
    roll: float | None = None
    focal: float | None = None
    hfov: float | None = None
    made: Camera | None = None

    def camera(self, default_image_size: tuple[int, int] | None = None) -> Camera:
        if self.made is not None:
            return self.made
        return camera_from_options(self.file, self.camera_height, self.pitch, self.image_size, self.roll, self.focal,
                                   self.hfov, default_image_size)


@dataclasses.dataclass(frozen=True)
class Job:
    """``inputs`` (keypoint files or videos) with their ``cameras`` (one each), lifted by ``checkpoint`` (the
    shipped model for the input's layout when None) in ``precision``; ``lift`` says how (its floor: the
    ``floor_file``'s regions, else each camera file's own, else z = 0); keypoints are read with ``layout``, ``fps``
    and ``read_options`` (a VideoPose3D npz's subject, action, camera_index); videos by ``detector``
    (``video.DEFAULT_DETECTOR`` when None) with ``video`` options; each input's world written as ``world_format``, a video's ``overlay`` drawn, outputs
    replaced only with ``overwrite``; several inputs are several cameras of one scene, their clocks found from
    the people with ``find_offsets``."""

    inputs: tuple  # paths; a live job's may be device numbers or stream URLs
    cameras: tuple[CameraChoice, ...]
    checkpoint: str | None = None
    precision: str = "fp32"
    lift: LiftOptions = LiftOptions()
    floor_file: str | None = None
    layout: str | None = None
    fps: float | None = None
    read_options: dict = dataclasses.field(default_factory=dict)
    detector: str | None = None
    video: VideoOptions = VideoOptions()
    world_format: str = ".json"
    overlay: bool = True
    find_offsets: bool = False
    overwrite: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "inputs", tuple(self.inputs))
        if not self.inputs:
            raise InputError("inputs: a job needs at least one input", ("inputs",))
        if len(self.cameras) != len(self.inputs):
            raise InputError(f"camera: {len(self.cameras)} given for {len(self.inputs)} inputs; give one per input, "
                             "in order", ("camera",))
        if self.world_format not in WRITTEN_FORMATS:
            raise InputError(f"format: {self.world_format!r} is not one of {', '.join(WRITTEN_FORMATS)}", ("format",))
        check_precision(self.precision)
        if self.floor_file is not None:
            read_floor(self.floor_file)  # a bad floor file is refused before any work

    @property
    def kind(self) -> str:
        return input_kind(self.inputs[0])

    def lift_options(self, k: int) -> LiftOptions:
        """Input ``k``'s lifting options, with the floor it rests on."""
        floor = read_floor(self.floor_file) if self.floor_file else floor_of_camera_file(self.cameras[k].file)
        floor_z = self.lift.floor_z if self.lift.floor_z is not None else floor_z_of_camera_file(self.cameras[k].file)
        return dataclasses.replace(self.lift, floor=floor, floor_z=floor_z)

    def lifter(self, layout: str | None = None, keypoints_path: str | Path | None = None):
        """The ``Lifter`` for keypoints of ``layout`` (``lifting.lifter.chosen_lifter``; None: the lifting chooses
        the shipped model for the input's layout itself)."""
        from ray3d.lifting.files import chosen_lifter

        return chosen_lifter(self.checkpoint, self.precision, layout, keypoints_path)
