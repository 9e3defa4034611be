"""Frame numbers from the ids other tools give their results' entries (COCO's ``image_id``, mmpose's
``frame_id``): a whole number is the frame; an image name's last number is ("frame_000012.png" is frame 12);
names with no number are numbered in the order they first appear. Ids that cannot be numbered, or whose frames
cannot be told apart, are refused naming the file and the field; how text was numbered is said
(``FrameNames.order``, printed by the command line)."""

from __future__ import annotations

from pathlib import Path

from ray3d.errors import InputError

FRAME_ORDERS = {"digits": "by the last number in each image name ('frame_000012.png' is frame 12)",
                "appearance": "in the order the image names first appear in the file (they hold no number)"}
MOST_FRAMES = 10_000_000_000  # a frame number beyond it names no frame of any recording (a year at 300 fps)


class FrameNames:
    """The frames of one results list's entries, numbered one id at a time (``number``), then checked as a whole
    (``check``)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.names: dict[str, tuple[int, str]] = {}  # image name -> (frame, rule of FRAME_ORDERS)
        self.numbered = False  # whether any id was a number
        self.field = "image_id"  # the field the ids came from, for the messages

    @property
    def order(self) -> str | None:
        """How names were put in order (``FRAME_ORDERS``' words), None when every id was a number."""
        return "; ".join(FRAME_ORDERS[r] for r in sorted({rule for _, rule in self.names.values()})) or None

    def number(self, image_id, field: str = "image_id") -> int:
        """The frame of one entry whose ``field`` holds ``image_id``: a whole number, or an image name; a number
        that is not whole (or beyond any frame count) or an id that is neither is refused."""
        self.field = field
        if isinstance(image_id, bool) or image_id is None:
            raise InputError(f"{self.path}: every entry needs an 'image_id' or 'frame_index'")
        if not isinstance(image_id, (int, float, str)):
            raise InputError(f"{self.path}: {field}: expected a frame number or an image name, got {image_id!r:.40}")
        if not isinstance(image_id, str):
            frame, self.numbered = image_id, True
        elif image_id in self.names:
            return self.names[image_id][0]
        else:
            signed = image_id.strip().lstrip("+-").isdecimal()  # "12" or "-3": the number itself, its sign kept
            digits = ([image_id.strip()] if signed
                      else "".join(c if c.isdigit() else " " for c in Path(image_id).stem).split())
            # By appearance: counted over every name, since a file that also numbers its names is refused (check).
            frame = int(digits[-1]) if digits else len(self.names)
            self.names[image_id] = (frame, "digits" if digits else "appearance")
        if isinstance(frame, float) and not frame.is_integer() or abs(frame) > MOST_FRAMES:
            raise InputError(f"{self.path}: {field} {image_id!r:.40}: not a frame number (expected a whole number up "
                             f"to {MOST_FRAMES:,}, or an image name whose last number is the frame)")
        return int(frame)

    def check(self) -> None:
        """Refuse names whose frames cannot be told apart: two names read as one frame (their last numbers agree),
        or names without a number beside frames given by number (counted from 0 by appearance, they would land on
        numbered frames)."""
        named: dict[int, str] = {}
        for name, (frame, rule) in self.names.items():
            if rule == "digits" and named.setdefault(frame, name) != name:
                raise InputError(f"{self.path}: {self.field}: {named[frame]!r:.40} and {name!r:.40} both read as frame "
                                 f"{frame} (the last number of each name): give each image its own number, or a "
                                 f"whole-number {self.field}")
        wordy = [name for name, (_, rule) in self.names.items() if rule == "appearance"]
        if wordy and (self.numbered or named):
            raise InputError(f"{self.path}: {self.field}: {len(wordy)} image name(s) hold no number ({wordy[0]!r:.40}) "
                             "beside frames given by number: no one order holds both; name every image by its frame "
                             "number")
