"""Where the ankle keypoints' rays meet the floor, observed from the people a camera sees rather than assumed.

A camera file's z = 0 is often not the floor people stand on (a calibration board on a table, a frame published
that way), and a detector's ankle keypoint of a planted foot stands at a height of its own (the shoes, the
detector). Together they put the *ankle plane*, the height at which the lowest ankle's ray meets where the person
stands, somewhere near ``contact_m`` over z = 0, not at it. From a camera near body height 1 cm of that plane moves
a person about 1 % of the distance, so it is estimated per camera, jointly over every track the camera saw, from
what does not depend on it: each person's size against an adult's. Scaled about the camera centre, a person's size
chain and the drop from the camera to their lowest ankle (on its observed ray) grow together, so their ratio is
read from the rays and the network's pose alone, whatever distance the network gave (the network's distance does
depend on the plane: it reads the camera's height as given, so it is no evidence of it). A person of the prior's
size then stands where ``log(centre_z - plane) = log(prior size) - log(size / drop)``.

Each track gives that equation with the spread of adults' sizes and of one track's measurement of its size
(``PERSON_SIZE_SD``, both measured on ``level-test``); the people share how far a site's population and a
detector's joints sit from the prior's mean (``POPULATION_MEAN_SD``), which many people do not average away; and
the plane has a prior of its own, the expected contact height over z = 0 give or take what users' calibrations are
off by (``PRIOR_SD_M``). One person for a few seconds barely moves it; ten or more place it to a few centimetres.

Cameras of one site share one floor, and where two see a person at once their ankle keypoints' rays cross where the
ankles are: triangulated, a planted ankle's height is the plane itself, to a few centimetres (``seen_twice``),
whatever the people's sizes.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import minimize_scalar

from ray3d import body
from ray3d.body import body_sizes, lowest_ankle_height
from ray3d.geometry.floor import LARGEST_FLOOR_Z_M, checked_floor_z

# A camera file's z = 0 lies within about 0.15 m of the floor when nothing else is known (users' calibrations on
# boards and steps are off by 0.1-0.15 m: issue 59).
PRIOR_SD_M = 0.15
# One track's log size against the prior: adults' spread and the network's reading of one person's size chain
# (level-test: the plane a person implies spreads 0.04 m about the truth given their true size, 0.15-0.17 m given
# the prior's, from cameras 0.9-1.5 m high, statures 1.45-1.95 m).
PERSON_SIZE_SD = 0.10
# How far the people of one site and one detector's joints stand from the prior's mean size, shared by them all.
POPULATION_MEAN_SD = 0.03
MIN_SECONDS = 0.5        # a track with less upright, feet-seen footage gives no evidence
MIN_DROP_M = 0.05        # the lowest ankle must stand this far below the camera for its ray to meet the floor
CONFIDENT_SHARE = 0.5    # observed: the people halved the prior's sd
GIVEN_SD_M = 0.03        # a floor the user gives: the detector's contact height is still a spread of its own
# Two cameras' rays of one person: the pelvis rays of one person pass within this of each other (a detector's
# hips, two calibrations); an ankle's two rays within this are taken to cross at it; cameras looking along one
# line (rays within 10 degrees) do not triangulate; a triangulated height is no better than the calibrations.
SAME_PERSON_GAP_M = 0.3
CROSSING_GAP_M = 0.15
MIN_CROSSING_SINE = np.sin(np.radians(10.0))
TRIANGULATION_SD_M = 0.02
LEG_HEIGHT_M = (0.4, 1.4)  # a standing person's pelvis over their lowest ankle (a child to the tallest adults)


@dataclasses.dataclass(frozen=True)
class SizeEvidence:
    """One track's evidence on the ankle plane: its camera centre's height ``centre_z`` and the median over its
    usable frames of log(size chain / drop from the camera to the lowest ankle), over ``seconds`` of footage."""

    centre_z: float
    log_size_over_drop: float
    seconds: float

    def implied_log_drop(self, body_size_m: float = body.ADULT_BODY_SIZE_M) -> float:
        """log(centre_z - plane) for a person whose size chain is ``body_size_m`` (the prior's; a detector's
        keypoints give a shorter one: ``body.DETECTOR_BODY_SIZE_M``)."""
        return float(np.log(body_size_m) - self.log_size_over_drop)


def size_evidence(joints: np.ndarray, centre: np.ndarray, usable: np.ndarray, fps: float) -> SizeEvidence | None:
    """(T, 17, 3) joints on their observed rays (any distance along them), the (3,) camera centre and the (T,)
    frames whose feet the detector saw -> the track's evidence, None with under ``MIN_SECONDS`` of upright
    frames whose lowest ankle stands below the camera."""
    joints = np.asarray(joints, dtype=np.float64)
    # At the prior's size first, so that which frames count (upright, feet below the camera) does not depend on
    # the distance the network gave either.
    sizes = body_sizes(joints)
    if not np.isfinite(sizes).any() or np.nanmedian(sizes) <= 0:
        return None
    joints = centre + body.ADULT_BODY_SIZE_M / np.nanmedian(sizes) * (joints - centre)
    drop = centre[2] - lowest_ankle_height(joints)
    upright = body.postures(joints, lowest_ankle_height(joints) - body.PLANTED_ANKLE_HEIGHT_M) \
        == body.POSTURES.index("upright")
    sizes = body_sizes(joints)
    frames = np.asarray(usable, dtype=bool) & upright & (drop > MIN_DROP_M) & (sizes > 0)
    if frames.sum() < MIN_SECONDS * fps:
        return None
    ratio = np.log(sizes[frames]) - np.log(drop[frames])
    return SizeEvidence(float(centre[2]), float(np.median(ratio)), float(frames.sum() / fps))


@dataclasses.dataclass(frozen=True)
class AnklePlane:
    """Where a camera's people's ankle keypoints meet the floor: ``height_m`` over the camera file's z = 0, with
    one sd ``sd_m``; ``contact_m`` is where a floor at z = 0 would put it (the detector's planted ankle);
    ``source``: "observed" (from ``people`` tracks over ``seconds``, ``seen_twice`` of them by two cameras at
    once), "prior" (nobody to observe it from) or "given" (the user's floor)."""

    height_m: float
    sd_m: float
    contact_m: float
    source: str
    people: int = 0
    seconds: float = 0.0
    seen_twice: int = 0

    @property
    def floor_z_m(self) -> float:
        """Where the floor people stand on lies in the camera file's frame (0: at its z = 0)."""
        return self.height_m - self.contact_m

    @property
    def confident(self) -> bool:
        return self.source == "given" or (self.source == "observed" and self.sd_m <= CONFIDENT_SHARE * PRIOR_SD_M)

    def message(self, camera: str = "") -> str:
        """One line for stderr: where the ankles meet the rays, against z = 0, and what was done with it."""
        which = f"camera {camera}'s" if camera else "this camera's"
        where = (f"people's ankles meet {which} rays {abs(self.height_m):.2f} +/- {self.sd_m:.2f} m "
                 f"{'above' if self.height_m >= 0 else 'below'} its z = 0 (the floor {abs(self.floor_z_m):.2f} m "
                 f"{'above' if self.floor_z_m >= 0 else 'below'} it")
        if self.source == "given":
            return f"{where}, as given); applied"
        if self.source == "prior":
            return f"{where}: assumed, nobody seen standing long enough to observe it); applied"
        seen = f"{self.people} {'person' if self.people == 1 else 'people'} over {self.seconds:.0f} s" + (
            f", {self.seen_twice} seen by two cameras at once" if self.seen_twice else "")
        if self.confident:
            return f"{where}, from {seen}); applied"
        return (f"{where}, from {seen}: too little to tell it well, the prior +/- {PRIOR_SD_M:.2f} m weighed in); "
                "applied")

    @classmethod
    def from_summary(cls, summary: dict) -> AnklePlane:
        """The plane a world file's ``summary`` records."""
        return cls(summary["height_m"], summary["sd_m"], summary["contact_m"], summary["source"], summary["people"],
                   summary["seconds"], summary.get("seen_twice", 0))

    def summary(self) -> dict:
        """Its record in world files."""
        return {"height_m": round(self.height_m, 4), "sd_m": round(self.sd_m, 4), "floor_z_m": round(self.floor_z_m, 4),
                "contact_m": round(self.contact_m, 4), "source": self.source, "confident": self.confident,
                "people": self.people, "seconds": round(self.seconds, 2), "seen_twice": self.seen_twice}


def given_ankle_plane(floor_z_m: float, contact_m: float) -> AnklePlane:
    """The plane of a floor the user states at ``floor_z_m`` in the camera file's frame."""
    floor_z_m = checked_floor_z(floor_z_m)
    return AnklePlane(floor_z_m + contact_m, GIVEN_SD_M, contact_m, "given")


@dataclasses.dataclass(frozen=True)
class SeenTwice:
    """One person seen by two cameras at once: the height of their planted ankle keypoints, triangulated
    (``height_m`` over the cameras' common z = 0, one sd ``sd_m``), over ``seconds`` seen by both."""

    height_m: float
    sd_m: float
    seconds: float
    pelvis_gap_m: float = 0.0  # how near the two pelvis rays pass (median): which pairing of two cameras' tracks


def seen_twice(centres: tuple[np.ndarray, np.ndarray], rays: tuple[np.ndarray, np.ndarray],
               seen: tuple[np.ndarray, np.ndarray], fps: float) -> SeenTwice | None:
    """Two cameras' (3,) ``centres`` and one track of each over the same (T,) frames: (T, 17, 3) world directions
    (any length) of their H36M-17 joints' rays and (T, 17) whether each joint was measured -> where the person's
    planted ankles stand, from the rays' crossings: per frame the lower of the two ankles (each where the rays pass
    within ``CROSSING_GAP_M``), the median over the frames. None when the tracks are not one person (their pelvis
    rays pass further apart than ``SAME_PERSON_GAP_M`` in most frames, or cross where no pelvis stands over those
    ankles), the cameras look along one line there, or they share under ``MIN_SECONDS`` of both ankles."""
    def crossing(joint: int) -> tuple[np.ndarray, np.ndarray]:
        """(T, 3) the midpoint of the two rays' nearest points and (T,) their gap (NaN: unmeasured, parallel or
        behind a camera)."""
        d_a, d_b = (ray[:, joint] / np.linalg.norm(ray[:, joint], axis=-1, keepdims=True) for ray in rays)
        offset = centres[0] - centres[1]
        cosine = np.einsum("ti,ti->t", d_a, d_b)
        spread = 1 - cosine ** 2
        along_a = np.einsum("ti,i->t", d_a, offset)
        along_b = np.einsum("ti,i->t", d_b, offset)
        with np.errstate(invalid="ignore", divide="ignore"):
            s = (cosine * along_b - along_a) / spread
            t = (along_b - cosine * along_a) / spread
        near_a, near_b = centres[0] + s[:, None] * d_a, centres[1] + t[:, None] * d_b
        usable = seen[0][:, joint] & seen[1][:, joint] & (spread > MIN_CROSSING_SINE ** 2) & (s > 0) & (t > 0)
        gap = np.where(usable, np.linalg.norm(near_a - near_b, axis=-1), np.nan)
        return np.where(usable[:, None], (near_a + near_b) / 2, np.nan), gap

    pelvis, pelvis_gap = crossing(body.PELVIS)
    both = np.isfinite(pelvis_gap)
    if both.sum() < MIN_SECONDS * fps or np.median(pelvis_gap[both]) > SAME_PERSON_GAP_M:
        return None
    ankles = [crossing(joint) for joint in body.ANKLES]
    heights = np.stack([np.where(gap <= CROSSING_GAP_M, point[:, 2], np.nan) for point, gap in ankles], axis=-1)
    lowest = heights.min(axis=-1)  # NaN unless both ankles crossed
    crossed = np.isfinite(lowest) & np.isfinite(pelvis[:, 2])
    legs = pelvis[crossed, 2] - lowest[crossed]
    lowest = lowest[crossed]
    if len(lowest) < MIN_SECONDS * fps or not LEG_HEIGHT_M[0] <= np.median(legs) <= LEG_HEIGHT_M[1]:
        return None
    spread = 1.4826 * np.median(np.abs(lowest - np.median(lowest)))
    seconds = len(lowest) / fps
    return SeenTwice(float(np.median(lowest)), float(np.hypot(spread / np.sqrt(max(seconds * 5, 1.0)),
                                                              TRIANGULATION_SD_M)), float(seconds),
                     float(np.median(pelvis_gap[both])))


def observe_ankle_plane(evidence: list[SizeEvidence | None], contact_m: float,
                        body_size_m: float = body.ADULT_BODY_SIZE_M, crossings: tuple = ()) -> AnklePlane:
    """The ankle plane of one floor from every track's ``size_evidence`` (None: a track that gave none), people's
    size chain being ``body_size_m`` on average, and the ankles two cameras saw at once (``crossings``: each a
    ``SeenTwice``), against the prior ``contact_m`` +/- ``PRIOR_SD_M``. The people's sizes are weighed robustly (a
    track more than three of its sds off the rest, a child or a detector's failure, is left out)."""
    given = [e for e in evidence if e is not None]
    crossings = [c for c in crossings if c is not None]
    information = 1 / PRIOR_SD_M ** 2 + sum(1 / c.sd_m ** 2 for c in crossings)
    weighed = contact_m / PRIOR_SD_M ** 2 + sum(c.height_m / c.sd_m ** 2 for c in crossings)
    if not given:
        if not crossings:
            return AnklePlane(contact_m, PRIOR_SD_M, contact_m, "prior")
        return AnklePlane(float(weighed / information), float(information ** -0.5), contact_m, "observed",
                          seconds=float(sum(c.seconds for c in crossings)), seen_twice=len(crossings))
    centre = np.array([e.centre_z for e in given])
    target = np.array([e.implied_log_drop(body_size_m) for e in given])
    sd = np.hypot(PERSON_SIZE_SD, 0.06 / np.sqrt(np.array([e.seconds for e in given])))
    kept = np.ones(len(given), dtype=bool)
    for _ in range(2):
        plane = _fit(centre[kept], target[kept], sd[kept])
        kept = np.abs(np.log(np.maximum(centre - plane, 1e-6)) - target) <= 3 * sd
        if not kept.any():
            kept[:] = True
    plane = _fit(centre[kept], target[kept], sd[kept])
    slope = 1 / (centre[kept] - plane)           # d log(centre_z - plane) / d plane, in magnitude
    weight = 1 / sd[kept] ** 2
    variance = 1 / np.sum(weight * slope ** 2) + (POPULATION_MEAN_SD / np.average(slope, weights=weight)) ** 2
    information, weighed = information + 1 / variance, weighed + plane / variance
    return AnklePlane(float(weighed / information), float(information ** -0.5), contact_m, "observed",
                      int(kept.sum()), float(sum(e.seconds for e, k in zip(given, kept) if k)), len(crossings))


def _fit(centre: np.ndarray, target: np.ndarray, sd: np.ndarray) -> float:
    """The plane height whose log drop from every camera centre best matches the tracks' (weighted)."""
    highest = min(float(centre.min()) - MIN_DROP_M, LARGEST_FLOOR_Z_M)

    def cost(plane: float) -> float:
        return float(np.sum(((np.log(centre - plane) - target) / sd) ** 2))

    return float(minimize_scalar(cost, bounds=(-LARGEST_FLOOR_Z_M, highest), method="bounded",
                                 options={"xatol": 1e-4}).x)
