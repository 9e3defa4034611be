"""Motion sets: clips of H36M-17 world positions in the shipped npz format, and the performer split.

The npz format (``../shared/data/mocap/README.md`` section 2): ``positions`` float32 (N, 17, 3) metres, z up,
floor z = 0; ``clip_start`` int64 (C + 1); per clip ``clip_id, subject, orig_subject, orig_take, source,
retargeted, fps, native_fps, description, floor_offset_m``; ``joint_names``, ``parents``.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from ray3d.body import ANKLES, PLANTED_ANKLE_HEIGHT_M
from ray3d.errors import InputError
from ray3d.io.atomic import atomic_path
from ray3d.io.dataset_files import DATASET_FPS
from ray3d.skeleton import H36M17

DATA_DIR_ENV = "RAY3D_DATA_DIR"
DATASETS = {"cmu": "cmu_h36m17.npz", "hdm05": "hdm05_h36m17.npz"}
SHIPPED_FILES = tuple(DATASETS.values())
CLIP_FIELDS = {
    "clip_id": str, "subject": str, "orig_subject": str, "orig_take": str, "source": str, "retargeted": bool,
    "fps": np.float32, "native_fps": np.float32, "description": str, "floor_offset_m": np.float32,
}
REQUIRED_KEYS = ("positions", "clip_start", "clip_id", "fps")

# Split by PERFORMER (orig_subject), never by clip: a person's other takes would leak their style and body.
# Validation and test each hold CMU and HDM05 performers; test performers are never used for training or
# model selection. Performers not listed (a user's own data included) are training data.
SPLITS = {
    "test": ("cmu_02", "cmu_07", "hdm05_mm"),
    "validation": ("cmu_03", "cmu_06", "hdm05_dg"),
}


@dataclasses.dataclass
class MotionSet:
    """Clips stacked in time: clip i is ``positions[clip_start[i]:clip_start[i + 1]]``."""

    positions: np.ndarray
    clip_start: np.ndarray
    clips: dict[str, np.ndarray]  # per-clip metadata, each (C,)

    @property
    def num_clips(self) -> int:
        return len(self.clip_start) - 1

    @property
    def num_frames(self) -> int:
        return len(self.positions)

    def clip(self, i: int) -> np.ndarray:
        return self.positions[self.clip_start[i]:self.clip_start[i + 1]]

    def clip_lengths(self) -> np.ndarray:
        return np.diff(self.clip_start)

    def select(self, keep: np.ndarray) -> MotionSet:
        """The clips where the boolean (C,) ``keep`` is True."""
        indices = np.flatnonzero(keep)
        lengths = self.clip_lengths()[indices]
        positions = (np.concatenate([self.clip(i) for i in indices]) if len(indices)
                     else self.positions[:0])
        return MotionSet(positions, np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
                         {k: v[indices] for k, v in self.clips.items()})

    @staticmethod
    def concatenate(sets: list[MotionSet]) -> MotionSet:
        lengths = np.concatenate([s.clip_lengths() for s in sets])
        return MotionSet(np.concatenate([s.positions for s in sets]),
                         np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
                         {k: np.concatenate([s.clips[k] for s in sets]) for k in CLIP_FIELDS})

    @classmethod
    def from_clips(cls, clips: list[np.ndarray], **metadata) -> MotionSet:
        """Build from (T_i, 17, 3) arrays; ``metadata`` gives per-clip values or one value for all clips."""
        lengths = [len(c) for c in clips]
        return cls(np.concatenate(clips).astype(np.float32), np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
                   _clip_fields(len(clips), metadata))

    # ------------------------------------------------------------------------------------------------ files
    @classmethod
    def load(cls, path: str | Path) -> MotionSet:
        """Read a motion npz (the shipped files, or one written by ``ray3d data import-*``)."""
        path = Path(path)
        try:
            data = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as err:
            raise InputError(f"{path}: cannot read as a motion npz ({err})") from None
        with data:
            missing = [k for k in REQUIRED_KEYS if k not in data.files]
            if missing:
                raise InputError(f"{path}: missing key(s) {', '.join(missing)}; a motion npz needs "
                                 f"{', '.join(REQUIRED_KEYS)} (see ray3d data info)")
            positions = data["positions"]
            clip_start = data["clip_start"].astype(np.int64)
            count = len(clip_start) - 1
            if positions.ndim != 3 or positions.shape[1:] != (17, 3):
                raise InputError(f"{path}: positions must be (N, 17, 3) H36M-17 joints, got {positions.shape}")
            if count < 1 or clip_start[0] != 0 or clip_start[-1] != len(positions) or np.any(np.diff(clip_start) <= 0):
                raise InputError(f"{path}: clip_start must rise from 0 to {len(positions)} (the number of frames)")
            if not np.isfinite(positions).all():
                raise InputError(f"{path}: positions contain NaN or infinite values")
            present = {key: data[key] for key in CLIP_FIELDS if key in data.files}
            wrong = [key for key, value in present.items() if value.shape != (count,)]
            if wrong:
                raise InputError(f"{path}: {', '.join(wrong)} must have one entry per clip ({count})")
            fields = _clip_fields(count, present)
        return cls(positions.astype(np.float32), clip_start, fields)

    def save(self, path: str | Path, overwrite: bool = False) -> None:
        """Write atomically in the shipped format; refuses to replace an existing file unless ``overwrite``."""
        with atomic_path(path, overwrite) as temporary:
            with open(temporary, "wb") as handle:
                np.savez_compressed(handle, positions=self.positions, clip_start=self.clip_start,
                                    joint_names=np.array(H36M17.joint_names), parents=np.array(H36M17.parents),
                                    **self.clips)


def _clip_fields(count: int, values: dict) -> dict[str, np.ndarray]:
    """Per-clip metadata arrays of length ``count``; absent fields get defaults (60 fps, native = fps,
    performer = body)."""
    fields: dict[str, np.ndarray] = {}
    for key, kind in CLIP_FIELDS.items():
        default = {"fps": 60.0, "native_fps": fields.get("fps"), "orig_subject": fields.get("subject")}.get(key)
        value = values.get(key, kind() if default is None else default)
        fields[key] = np.broadcast_to(np.asarray(value).astype(kind), (count,)).copy()
    return fields


def split_of(orig_subject: str) -> str:
    """'train', 'validation' or 'test' for a performer."""
    for split, performers in SPLITS.items():
        if orig_subject in performers:
            return split
    return "train"


def select_split(motion: MotionSet, split: str) -> MotionSet:
    if split not in ("train", "validation", "test", "all"):
        raise InputError(f"unknown split {split!r}; one of train, validation, test, all")
    if split == "all":
        return motion
    return motion.select(np.array([split_of(s) == split for s in motion.clips["orig_subject"]]))


def default_data_dir() -> Path | None:
    """Where the shipped mocap lives: ``$RAY3D_DATA_DIR``, else ``../shared/data/mocap`` beside the working
    directory or beside this source checkout; None when none of them has the files."""
    if os.environ.get(DATA_DIR_ENV):
        return Path(os.environ[DATA_DIR_ENV])
    candidates = [Path.cwd() / ".." / "shared" / "data" / "mocap",
                  Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "mocap"]
    for candidate in candidates:
        if all((candidate / f).is_file() for f in SHIPPED_FILES):
            return candidate.resolve()
    return None


def resolve_data_dir(data_dir: str | Path | None = None) -> Path:
    """``data_dir`` or the default; an error that says what to do when there is no data."""
    path = Path(data_dir) if data_dir else default_data_dir()
    if path is None:
        raise InputError(f"no motion data found: name a folder holding {' and '.join(SHIPPED_FILES)} (the "
                         f"repository's ../shared/data/mocap) or set {DATA_DIR_ENV} to one, or give a motion npz of "
                         "your own (the BVH and ASF/AMC importers make one)", arguments=("data_dir",))
    found = [f for f in SHIPPED_FILES if (path / f).is_file()]
    if not found:
        raise InputError(f"{path}: holds none of {', '.join(SHIPPED_FILES)}")
    return path


def load_shipped(data_dir: str | Path | None = None, split: str = "all",
                 datasets: tuple[str, ...] = tuple(DATASETS)) -> MotionSet:
    """The CMU and HDM05 motion sets (whichever are present; or only ``datasets`` of them), restricted to
    ``split``."""
    unknown = set(datasets) - set(DATASETS)
    if unknown or not datasets:
        raise InputError(f"datasets: {sorted(unknown) or 'none given'}; choose from {', '.join(DATASETS)}")
    path = resolve_data_dir(data_dir)
    files = [DATASETS[name] for name in datasets]
    sets = [MotionSet.load(path / f) for f in files if (path / f).is_file()]
    if not sets:
        raise InputError(f"{path}: holds none of {', '.join(files)}")
    return select_split(ground_performers(MotionSet.concatenate(sets)), split)


# A lowest ankle moving slower than this (m/s) is planted; a clip's planted height is this percentile of its
# planted frames' heights (a climber's or a stair walker's other stances stand higher).
PLANTED_SPEED_M_S = 0.1
PLANTED_PERCENTILE = 10.0


def planted_ankle_heights(motion: MotionSet) -> dict[str, float]:
    """Per performer (``orig_subject``): how high the lowest ankle joint stands over the floor when planted,
    the median over their clips of each clip's ``PLANTED_PERCENTILE`` of planted-frame heights (NaN where no
    clip has a planted frame). Datasets place the ankle joint differently (HDM05's dg sits 0.16 m up, CMU's 05
    0.03 m)."""
    heights: dict[str, list[float]] = {}
    for i in range(motion.num_clips):
        ankles = motion.clip(i)[:, list(ANKLES)].astype(np.float64)
        lower = np.argmin(ankles[1:, :, 2], axis=1)
        speed = np.linalg.norm(np.diff(ankles, axis=0), axis=-1)[np.arange(len(lower)), lower] * motion.clips["fps"][i]
        height = ankles[1:, :, 2][np.arange(len(lower)), lower]
        planted = height[speed < PLANTED_SPEED_M_S]
        if len(planted):
            heights.setdefault(str(motion.clips["orig_subject"][i]), []).append(
                float(np.percentile(planted, PLANTED_PERCENTILE)))
    return {performer: float(np.median(values)) for performer, values in heights.items()}


def ground_performers(motion: MotionSet, planted_height_m: float = PLANTED_ANKLE_HEIGHT_M) -> MotionSet:
    """``motion`` with each performer raised or lowered so that their planted ankle stands ``planted_height_m``
    over the floor (``planted_ankle_heights``), the shift added to the clips' ``floor_offset_m``: the floor the
    network learns and the floor the refinement assumes are then one floor."""
    shift = planted_ankle_heights(motion)
    per_clip = np.array([planted_height_m - shift.get(str(s), planted_height_m) for s in motion.clips["orig_subject"]])
    per_frame = np.repeat(per_clip, motion.clip_lengths()).astype(np.float32)
    positions = motion.positions.copy()
    positions[..., 2] += per_frame[:, None]
    clips = {**motion.clips, "floor_offset_m": (motion.clips["floor_offset_m"] - per_clip).astype(np.float32)}
    return MotionSet(positions, motion.clip_start, clips)


def summary(motion: MotionSet) -> dict:
    """Counts for ``ray3d data info``: clips, frames, minutes, and per performer, body and split."""
    lengths = motion.clip_lengths()
    minutes = lengths / motion.clips["fps"] / 60.0

    def by(key_values: np.ndarray) -> dict:
        table: dict[str, dict] = {}
        for key, frames, mins in zip(key_values, lengths, minutes):
            row = table.setdefault(str(key), {"clips": 0, "frames": 0, "minutes": 0.0})
            row["clips"] += 1
            row["frames"] += int(frames)
            row["minutes"] += float(mins)
        return table

    return {
        "clips": motion.num_clips, "frames": motion.num_frames, "minutes": float(minutes.sum()),
        "splits": by(np.array([split_of(s) for s in motion.clips["orig_subject"]])),
        "performers": by(motion.clips["orig_subject"]), "bodies": by(motion.clips["subject"]),
    }


def to_motion_set(positions: dict[str, dict[str, np.ndarray]], dataset: str) -> MotionSet:
    """A motion set (one clip per subject and action) from 17-joint positions (``ray3d.io.dataset_files``),
    e.g. to evaluate on them."""
    clips, ids, subjects = [], [], []
    for subject, actions in positions.items():
        for action, array in actions.items():
            if array.shape[1] != H36M17.num_joints:
                raise InputError(f"{dataset} {subject}/{action}: motion sets hold H36M-17 joints, got "
                                 f"{array.shape[1]} (HumanEva converts to the 14-joint layout only)")
            clips.append(array)
            ids.append(f"{subject}_{action}".replace(" ", "_"))
            subjects.append(subject)
    if not clips:
        raise InputError(f"{dataset}: no clips")
    return MotionSet.from_clips(clips, clip_id=ids, subject=subjects, source=dataset, fps=DATASET_FPS[dataset],
                                description=[i.split("_", 1)[1] for i in ids])
