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
from ray3d.io.floor_memory import floor_memory_path, input_key, read_floor_memory, remember_floor
from ray3d.io.world import WRITTEN_FORMATS
from ray3d.lifting.lifter import Lifter
from ray3d.lifting.options import LiftOptions, VideoOptions
from ray3d.models.precision import check_precision
from ray3d.refine.ankle_plane import SeenTwice, SizeEvidence
from ray3d.site.files import read_site
from ray3d.skeleton import layout_skeleton

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
    (``video.DEFAULT_DETECTOR`` when None) with ``video`` options; each input's world written as ``world_format``, a
    video's ``overlay`` drawn, outputs replaced only with ``overwrite``; several inputs are several cameras of one
    scene, their clocks found from the people with ``find_offsets``; with a ``site`` file, the people's report on its
    zones and lines (time buckets of ``every_s`` seconds from ``start_time``, a ``datetime``). With ``remember_floor``,
    what each camera's people show of its floor is kept beside its camera file and weighed in by the next job
    (``io.floor_memory``)."""

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
    site: str | Path | None = None
    every_s: float | None = None
    start_time: Any = None
    remember_floor: bool = True
    _lifters: dict = dataclasses.field(default_factory=dict, init=False, repr=False, compare=False)

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
        if self.every_s is not None and (isinstance(self.every_s, bool) or not isinstance(self.every_s, (int, float))
                                         or not 0 < self.every_s < float("inf")):
            raise InputError(f"every_s: the time buckets' length in seconds, above 0; got {self.every_s!r}",
                             ("every_s",))
        if self.start_time is not None and self.every_s is None:
            raise InputError("start_time places the time buckets: give every_s too", ("start_time", "every_s"))
        if self.site is not None:
            if not isinstance(self.site, (str, Path)):
                raise InputError(f"site: a site file's path; got {type(self.site).__name__}", ("site",))
            object.__setattr__(self, "site", Path(self.site))
            self.site_plan()  # a bad site file is refused before any work

    def __getstate__(self) -> dict:
        return {**self.__dict__, "_lifters": {}}  # a job sent to a Ray worker loads its models there

    @property
    def kind(self) -> str:
        return input_kind(self.inputs[0])

    def lift_options(self, k: int) -> LiftOptions:
        """Input ``k``'s lifting options, by which both clocks lift its camera (``ray3d lift``, ``ray3d video``,
        batch rows and live alike): the floor it rests on (the ``floor_file``'s regions, else its camera file's),
        where that floor lies (the site's, ``floor_z``) and, where that is to be observed, what its camera's people
        showed of it in earlier jobs (``remembered_floor``)."""
        floor = read_floor(self.floor_file) if self.floor_file else floor_of_camera_file(self.cameras[k].file)
        floor_z = self.site_floor_z()
        remembered = self.remembered_floor(k) if floor_z is None else ()
        return dataclasses.replace(self.lift, floor=floor, floor_z=floor_z,
                                   seen_before=(*self.lift.seen_before, *remembered))

    def site_floor_z(self) -> float | None:
        """Where the floor of the job's cameras lies, one site's one floor: the job's own (``--floor-z``), else
        the one their camera files declare (``floor_z_m``: a file that declares none stands on it too; files
        that place it differently are refused), else None (observed from the people)."""
        if self.lift.floor_z is not None:
            return self.lift.floor_z
        declared = {}
        for choice in self.cameras:
            if (floor_z := floor_z_of_camera_file(choice.file)) is not None:
                declared.setdefault(floor_z, choice.file)
        if len(declared) > 1:
            (first, first_file), (second, second_file) = list(declared.items())[:2]
            raise InputError(f"{second_file}: floor_z_m {second:g} where {first_file} says {first:g}: the cameras of "
                             "one site stand on one floor", ("camera", "floor_z"))
        return next(iter(declared), None)

    def floor_memory(self, k: int) -> Path | None:
        """Where input ``k``'s camera's floor memory lies (beside its camera file); None for a camera without a
        file or a job that does not remember."""
        return floor_memory_path(self.cameras[k].file) if self.remember_floor and self.cameras[k].file else None

    def remembered_floor(self, k: int) -> tuple:
        """What input ``k``'s camera's people showed of its floor in earlier jobs (not this one's inputs again):
        its people's sizes and, once per earlier job, the ankles two of this job's cameras saw at once."""
        key = input_key(*self.inputs)
        earlier_jobs = set()
        for j in range(k):
            path = self.floor_memory(j)
            if path is not None:
                earlier_jobs |= {run.key for run in read_floor_memory(path, self.cameras[j].camera())}
        path = self.floor_memory(k)
        runs = [run for run in ([] if path is None else read_floor_memory(path, self.cameras[k].camera()))
                if run.key != key]
        return (*(e for run in runs for e in run.people),
                *(e for run in runs if run.key not in earlier_jobs for e in run.ankles))

    def remember_floor_seen(self, k: int, evidence: tuple) -> None:
        """Keeps what input ``k``'s camera's people showed of its floor in this job (``World.floor_evidence``) in
        its floor memory, in place of what the same inputs showed before."""
        path = self.floor_memory(k)
        if path is not None and evidence:
            remember_floor(path, self.cameras[k].camera(), input_key(*self.inputs),
                           tuple(e for e in evidence if isinstance(e, SizeEvidence)),
                           tuple(e for e in evidence if isinstance(e, SeenTwice)))

    def lifter(self, layout: str | None = None):
        """The ``Lifter`` for keypoints of ``layout`` (``load_lifter``; None: H36M-17), loaded once per layout."""
        layout = layout or "h36m17"
        if layout not in self._lifters:
            self._lifters[layout] = load_lifter(self.checkpoint, self.precision, layout)
        return self._lifters[layout]

    def site_plan(self):
        """The ``site.places.Site`` of ``site`` (None without one)."""
        return None if self.site is None else read_site(self.site)


def load_lifter(checkpoint: str | None = None, precision: str = "fp32", layout: str | None = None):
    """The model a job or a benchmark lifts by: ``checkpoint`` (a shipped name or a path; None: the shipped model for
    keypoints of ``layout``, H36M-17 when None) in ``precision``."""
    return Lifter.load(checkpoint, layout=layout_skeleton(layout or "h36m17").name, precision=precision)
