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
detector's size chain sit from the prior's mean (``body.POPULATION_SIZE_SD``, ``body.KeypointSource``), which many
people do not average away: from a camera 1 m above the ankles 4 % of size is 4 cm of floor, whatever the crowd.

So the people's floor is evidence, not an answer: it is weighed against the camera file's own (the detector's
planted ankle over z = 0, known to its ``planted_ankle_sd_m``) as a model comparison, and the file's floor is
kept unless the people show it is more likely off than not (``decide_ankle_plane``), said either way.

Cameras of one site share one floor, and where two see a person at once their ankle keypoints' rays cross where the
ankles are: triangulated, a planted ankle's height is the plane itself, to a few centimetres (``seen_twice``),
whatever the people's sizes.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.stats import norm

from ray3d import body
from ray3d.body import body_sizes, lowest_ankle_height
from ray3d.errors import InputError
from ray3d.geometry.floor import LARGEST_FLOOR_Z_M, checked_floor_z

# Before its people are seen: the chance that a camera file's z = 0 is off the floor people stand on (most
# calibrations are right: issue 66; those on boards and steps are off by 0.1-0.15 m: issue 59), and by how much
# when it is. The people's evidence is weighed against both: the floor found is applied only where it is off
# beyond reasonable doubt, three to one. Even odds would minimise the expected squared error if the evidence's
# shared part (the population's size) were known, but it is not: on level-test, a population 4 % taller or shorter
# than the prior then moved right floors in 9-10 % of cameras, worse than keeping them (0.45 / 0.40 of the guess's
# error against 0.40 / 0.36), while three to one keeps them (0.40 / 0.36) and still applies the people's floor to
# 46-54 % of cameras 0.15 m off (results-2026-12-07.md, "How sure before the floor moves").
PRIOR_CHANCE_OFF = 0.5
PRIOR_SD_M = 0.15
APPLY_CHANCE = 0.75
# One track's log size against the prior: adults' spread and the network's reading of one person's size chain
# (level-test: the plane a person implies spreads 0.04 m about the truth given their true size, 0.15-0.17 m given
# the prior's, from cameras 0.9-1.5 m high, statures 1.45-1.95 m). What people share, and many do not average
# away, is the population's mean size and the detector's own size chain (``body.KeypointSource``).
PERSON_SIZE_SD = 0.10
MIN_SECONDS = 0.5        # a track with less upright, feet-seen footage gives no evidence
MIN_DROP_M = 0.05        # the lowest ankle must stand this far below the camera for its ray to meet the floor
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


def checked_evidence(evidence) -> tuple:
    """What people showed of a floor before (``SizeEvidence`` and ``SeenTwice`` in any iterable) as a tuple; an
    ``InputError`` naming ``seen_before`` for anything else."""
    try:
        evidence = tuple(evidence)
    except TypeError:
        raise InputError(f"seen_before: SizeEvidence and SeenTwice of earlier lifts; got {type(evidence).__name__}",
                         ("seen_before",)) from None
    strangers = {type(e).__name__ for e in evidence if not isinstance(e, (SizeEvidence, SeenTwice))}
    if strangers:
        raise InputError("seen_before: SizeEvidence and SeenTwice of earlier lifts; got "
                         f"{', '.join(sorted(strangers))}", ("seen_before",))
    return evidence


def floor_evidence(evidence: SizeEvidence, contact_m: float, body_size_m: float) -> SizeEvidence:
    """A track's evidence of its ankle plane, from keypoints whose planted ankles stand ``contact_m`` over the
    floor and whose size chain is ``body_size_m`` for an adult of the prior's size, as evidence of the floor itself
    (for keypoints at the floor of the mocap's size chain): how cameras with different detectors pool theirs."""
    return SizeEvidence(evidence.centre_z - contact_m,
                        evidence.log_size_over_drop + float(np.log(body.ADULT_BODY_SIZE_M / body_size_m)),
                        evidence.seconds)


@dataclasses.dataclass(frozen=True)
class AnklePlane:
    """Where a camera's people's ankle keypoints meet the floor: ``height_m`` over the camera file's z = 0, with
    one sd ``sd_m`` (the expected error of the plane used, the decision's chance of being wrong included);
    ``contact_m`` is where a floor at z = 0 puts it (the detector's planted ankle). ``source``: "observed" (the
    people ``observed_m`` +/- ``observed_sd_m``, from ``people`` tracks over ``seconds``, ``seen_twice`` of them
    by two cameras at once), "prior" (nobody to observe it from) or "given" (the user's floor); ``decision``:
    "kept" (the camera file's floor) or "applied" (the people's, more likely right than not: ``chance_off``, the
    chance that the camera file's floor is off)."""

    height_m: float
    sd_m: float
    contact_m: float
    source: str
    people: int = 0
    seconds: float = 0.0
    seen_twice: int = 0
    decision: str = "applied"
    chance_off: float | None = None
    observed_m: float | None = None
    observed_sd_m: float | None = None

    @property
    def floor_z_m(self) -> float:
        """Where the floor people stand on lies in the camera file's frame (0: at its z = 0)."""
        return self.height_m - self.contact_m

    def message(self, camera: str = "") -> str:
        """One line for stderr: what the people say of the camera's floor, what was done and what to do."""
        which = f"camera {camera}" if camera else "the camera"
        if self.source == "given":
            return f"{which}: the floor as given, {_offset(self.floor_z_m)} its z = 0; applied"
        if self.source == "prior":
            return (f"{which}: nobody seen standing long enough to check its floor; its z = 0 kept as the floor (a "
                    f"{self.chance_off:.0%} chance it is off, before any evidence)")
        seen = f"{self.people} {'person' if self.people == 1 else 'people'} seen standing" + (
            f" for {self.seconds:.0f} s in all" if self.people else "") + (
            f", {self.seen_twice} by two cameras at once" if self.seen_twice else "")
        floor = self.observed_m - self.contact_m  # where the people put the floor against z = 0
        if self.decision == "kept":
            return (f"{which}: the people fit its floor (they put it {_offset(floor, self.observed_sd_m)} its "
                    f"z = 0, within what people's sizes and the detector leave; a {self.chance_off:.0%} chance it is "
                    f"off; {seen}); kept, nothing to do")
        return (f"{which}: its z = 0 seems {_offset(-floor, self.observed_sd_m)} the floor ({self.chance_off:.0%} "
                f"sure; {seen}); applied; to fix it for good, measure the lens's height over the floor and run "
                "ray3d calibrate --floor-of CAMERA --lens-height M (it writes floor_z_m into the camera file)")

    def standing(self, contact_m: float) -> AnklePlane:
        """The plane of keypoints whose planted ankles stand ``contact_m`` over the floor this one places (a floor's
        own plane: contact 0)."""
        rise = contact_m - self.contact_m
        return dataclasses.replace(self, height_m=self.height_m + rise, contact_m=contact_m,
                                   observed_m=None if self.observed_m is None else self.observed_m + rise)

    @classmethod
    def from_summary(cls, summary: dict) -> AnklePlane:
        """The plane a world file's ``summary`` records."""
        return cls(summary["height_m"], summary["sd_m"], summary["contact_m"], summary["source"],
                   summary.get("people", 0), summary.get("seconds", 0.0), summary.get("seen_twice", 0),
                   summary.get("decision", "applied"), summary.get("chance_off"), summary.get("observed_m"),
                   summary.get("observed_sd_m"))

    def summary(self) -> dict:
        """Its record in world files."""
        def rounded(value):
            return None if value is None else round(value, 4)

        return {"height_m": round(self.height_m, 4), "sd_m": round(self.sd_m, 4), "floor_z_m": round(self.floor_z_m, 4),
                "contact_m": round(self.contact_m, 4), "source": self.source, "decision": self.decision,
                "chance_off": rounded(self.chance_off), "observed_m": rounded(self.observed_m),
                "observed_sd_m": rounded(self.observed_sd_m), "people": self.people,
                "seconds": round(self.seconds, 2), "seen_twice": self.seen_twice}


def _offset(value: float, sd: float | None = None) -> str:
    """'0.12 +/- 0.03 m below' for -0.12 (sd 0.03)."""
    spread = "" if sd is None else f" +/- {sd:.2f}"
    return f"{abs(value):.2f}{spread} m {'above' if value >= 0 else 'below'}"


def given_ankle_plane(floor_z_m: float, contact_m: float, contact_sd_m: float) -> AnklePlane:
    """The plane of a floor the user states at ``floor_z_m`` in the camera file's frame, the detector's planted
    ankle ``contact_m`` +/- ``contact_sd_m`` over it."""
    floor_z_m = checked_floor_z(floor_z_m)
    return AnklePlane(floor_z_m + contact_m, contact_sd_m, contact_m, "given", decision="given")


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


@dataclasses.dataclass(frozen=True)
class PlaneObservation:
    """What a floor's people say of its ankle plane on their own (no prior): ``height_m`` +/- ``sd_m`` over z = 0,
    from ``people`` tracks' sizes over ``seconds`` and ``seen_twice`` people's triangulated ankles."""

    height_m: float
    sd_m: float
    people: int
    seconds: float
    seen_twice: int


def observe_plane(evidence: list[SizeEvidence | None], body_size_m: float, size_source_sd: float = 0.0,
                  crossings: tuple = ()) -> PlaneObservation | None:
    """The ankle plane every track's ``size_evidence`` (None: a track that gave none) and the ankles two cameras
    saw at once (``crossings``: each a ``SeenTwice``) place, without a prior: people's size chain being
    ``body_size_m`` on average, up to the population's mean size (``body.POPULATION_SIZE_SD``) and the detector's
    own (``size_source_sd``), which every track shares. The sizes are weighed robustly (a track more than three of
    its sds off the rest, a child or a detector's failure, is left out). None: nothing to observe it from."""
    given = [e for e in evidence if e is not None]
    crossings = [c for c in crossings if c is not None]
    information = sum(1 / c.sd_m ** 2 for c in crossings)
    weighed = sum(c.height_m / c.sd_m ** 2 for c in crossings)
    seconds, people = float(sum(c.seconds for c in crossings)), 0
    if given:
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
        shared = np.hypot(body.POPULATION_SIZE_SD, size_source_sd)
        variance = 1 / np.sum(weight * slope ** 2) + (shared / np.average(slope, weights=weight)) ** 2
        information, weighed = information + 1 / variance, weighed + plane / variance
        people = int(kept.sum())
        seconds += float(sum(e.seconds for e, k in zip(given, kept) if k))
    if not information:
        return None
    return PlaneObservation(float(weighed / information), float(information ** -0.5), people, seconds,
                            len(crossings))


def decide_ankle_plane(observed: PlaneObservation | None, contact_m: float, contact_sd_m: float,
                       prior_chance_off: float = PRIOR_CHANCE_OFF) -> AnklePlane:
    """The camera file's floor (the plane at ``contact_m`` +/- ``contact_sd_m``, the detector's) against a floor
    anywhere near it (+/- ``PRIOR_SD_M``), weighed on what the people ``observed``: the Bayes factor of the two,
    from the chance ``prior_chance_off`` that a camera file's floor is off, gives the chance that it is; the
    people's floor (the observation under the second, with its prior) is applied where that chance reaches
    ``APPLY_CHANCE`` and they tell the floor to ``PRIOR_SD_M`` or better, else the file's is kept. The plane's sd:
    kept, the detector's own spread and, weighed by the chance that the file's floor is off, the step the people
    would take it by (a right calibration's people, who show little, leave it near the detector's: it covers 55-85 %
    within 1 sd on ``level-test`` and the emulated street split); applied, the expected error of the people's
    estimate, the chance that the file's was right in it; nobody seen, the prior's mixture."""
    kept_variance = contact_sd_m ** 2
    if observed is None:
        sd = np.sqrt((1 - prior_chance_off) * kept_variance + prior_chance_off * PRIOR_SD_M ** 2)
        return AnklePlane(contact_m, float(sd), contact_m, "prior", decision="kept", chance_off=prior_chance_off)
    free_variance = PRIOR_SD_M ** 2 + kept_variance
    seen_variance = observed.sd_m ** 2
    residual = observed.height_m - contact_m
    log_factor = (norm.logpdf(residual, scale=np.sqrt(seen_variance + free_variance))
                  - norm.logpdf(residual, scale=np.sqrt(seen_variance + kept_variance)))
    odds = prior_chance_off / (1 - prior_chance_off) * np.exp(np.clip(log_factor, -50, 50))
    chance = float(odds / (1 + odds))
    # The plane if off: the observation with the free floor's prior.
    off_variance = 1 / (1 / free_variance + 1 / seen_variance)
    off_height = contact_m + off_variance * residual / seen_variance
    shift = (off_height - contact_m) ** 2
    # People who tell the floor no better than calibrations are off by cannot show one off: the chance then stays
    # near even whatever they show (a street camera's crowd, 0.2-0.4 m), and the file's floor is kept.
    applied = chance >= APPLY_CHANCE and observed.sd_m <= PRIOR_SD_M
    if applied:
        height, variance = off_height, chance * off_variance + (1 - chance) * (kept_variance + shift)
    else:
        height, variance = contact_m, kept_variance + chance * shift
    return AnklePlane(float(height), float(np.sqrt(variance)), contact_m, "observed", observed.people,
                      observed.seconds, observed.seen_twice, "applied" if applied else "kept", chance,
                      observed.height_m, observed.sd_m)


def observe_ankle_plane(evidence: list[SizeEvidence | None], contact_m: float, contact_sd_m: float,
                        body_size_m: float = body.ADULT_BODY_SIZE_M, size_source_sd: float = 0.0,
                        crossings: tuple = ()) -> AnklePlane:
    """The ankle plane of one floor: what every track's ``size_evidence`` and the ``crossings`` of people two
    cameras saw at once say of it (``observe_plane``), decided against the camera file's floor
    (``decide_ankle_plane``)."""
    return decide_ankle_plane(observe_plane(evidence, body_size_m, size_source_sd, crossings), contact_m,
                              contact_sd_m)


def _fit(centre: np.ndarray, target: np.ndarray, sd: np.ndarray) -> float:
    """The plane height whose log drop from every camera centre best matches the tracks' (weighted)."""
    highest = min(float(centre.min()) - MIN_DROP_M, LARGEST_FLOOR_Z_M)

    def cost(plane: float) -> float:
        return float(np.sum(((np.log(centre - plane) - target) / sd) ** 2))

    return float(minimize_scalar(cost, bounds=(-LARGEST_FLOOR_Z_M, highest), method="bounded",
                                 options={"xatol": 1e-4}).x)
