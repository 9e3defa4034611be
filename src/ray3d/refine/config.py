"""What the refinement weighs its cues by (``RefineConfig``, with what each model measured of itself) and what
it found for a track (``Refinement``)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ray3d import body
from ray3d.errors import InputError
from ray3d.geometry.arrays import numeric_array
from ray3d.skeleton import DETECTOR_LAYOUTS, H36M17, Skeleton, layout_skeleton

EVIDENCE_FPS = 30.0  # per-frame evidence is weighed as if the footage ran at this rate
UNCERTAINTY_SAMPLES = 200  # frames at which the covariance is evaluated; the rest are interpolated
PINNED_SD = 1e-6  # the prior of a term held at its value
# The root, the mean of two hips smoothed in time, errs across its ray by about a third of one keypoint: 0.0104 of
# the size chain on the detector-emulated split (`ray3d-real`, savgol) against a keypoint error of 0.03.
ROOT_KEYPOINT_SHARE = 0.35
UNCERTAINTY_FIELDS = ("depth_sd", "depth_bias_sd", "floor_offset_sd_m",
                      "residual_distance_sd")  # what a model measures of itself
# The cues a frame's distance is read from, in the order of ``Refinement.cue_shares``.
CUES = ("network", "floor", "head", "size")


@dataclasses.dataclass(frozen=True)
class RefineConfig:
    """The uncertainties the cues are weighed by (metres, or fractions of a distance or size).

    The planted ankle's height and the body-size prior are ``ray3d.body``'s, measured on the training
    performers of the shipped mocap. ``depth_bias_sd`` is (distance m, relative sd) pairs, interpolated: the rms
    of the shipped ``ray3d``'s relative distance error by the distance it predicts, GT 2D, test performers, every
    camera set (docs/RESULTS.md, "Never worse than the network": beyond 15 m it predicts people much too close).
    """

    contact_ankle_height_m: float = body.PLANTED_ANKLE_HEIGHT_M
    # The keypoints' source (``body.KeypointSource``): where its ankle keypoints' rays meet a planted foot over the
    # floor and how well that is known (m; what the floor's evidence and a triangulated ankle are read against,
    # not where the refined pose's lowest ankle rests: that is ``contact_ankle_height_m``), the size chain the
    # network's pose on its rays reads for an adult of the prior's size, and how well (relative), each shared by
    # everybody it sees.
    keypoint_ankle_height_m: float = body.KEYPOINT_SOURCES["h36m17"].planted_ankle_m
    keypoint_ankle_sd_m: float = body.KEYPOINT_SOURCES["h36m17"].planted_ankle_sd_m
    read_size_m: float = body.KEYPOINT_SOURCES["h36m17"].read_size_m
    read_size_sd: float = body.KEYPOINT_SOURCES["h36m17"].read_size_sd
    ankle_height_sd_m: float = 0.05          # contact-height spread plus the network's ankle error, per frame
    # An upright head's height over the floor against the track's size: the head's bob and lean and the network's
    # head error, per frame; and one person's head-to-size ratio against the prior's, per track (3 % of 1.6 m).
    head_height_sd_m: float = 0.05
    head_offset_sd_m: float = 0.05
    # One person's planted-ankle height against the prior (the floor test), and where their pelvis rests over
    # the floor against the network's pose on the prior (that and the pose's error; the uncertainty), per track.
    contact_height_sd_m: float = 0.02
    floor_offset_sd_m: float = 0.035
    # What the cues leave of the distance's error, as a share of it (the network's pose seen from afar and from
    # above: docs/RESULTS.md, "Never worse than the network"); added to the solution's own uncertainty.
    residual_distance_sd: float = 0.0065
    body_size_m: float = body.ADULT_BODY_SIZE_M      # prior on the size chain of an adult
    body_size_sd: float = body.ADULT_BODY_SIZE_SD    # relative
    frame_size_sd: float = 0.06              # relative error of one frame's predicted body size
    depth_sd: tuple[float, float] = (0.03, 0.006)  # the network's relative depth error: a + b * distance (m)
    depth_bias_sd: tuple[tuple[float, float], ...] = ((0.0, 0.04), (8.0, 0.045), (10.0, 0.06), (12.0, 0.075),
                                                       (15.0, 0.1), (16.0, 0.4), (20.0, 0.6), (60.0, 1.0))
    distance_acceleration_sd: float = 0.3    # of the log of the person's distance, per second^1.5
    robust_scale: float = 2.0                # residuals (in standard deviations) beyond which the loss is linear
    # Across its ray, a joint of the network's shape hung from the root is off by 0.017 m per axis (the shipped
    # `ray3d`, training performers, h36m cameras); a keypoint detector errs by a few per cent of the person's
    # size in the image, which at the person is the same fraction of their size in metres, at any distance.
    pose_lateral_sd_m: float = 0.02
    keypoint_error: float = 0.03             # of the body-size chain, per axis; 0 for exact 2D
    agreement_window_s: float = 2.0          # the stretch over which the floor is tested against the network
    agreement_sigmas: float = 2.0            # a disagreement beyond this many joint sds drops the floor there
    # A floor further from z = 0 (or the declared one) than this is not believed: the network is wrong instead
    # (loading docks, stages and beds stand 0.4-1.3 m high).
    largest_floor_step_m: float = 1.5
    # The floor is tested only where the network places it to within this (1 sd): near, and seen from above.
    floor_test_resolution_m: float = 0.15
    size_cue_margin: float = 0.05            # log size: how much nearer the floor's the size must be to side with it
    # How well the ankle plane is known (``ray3d.refine.ankle_plane``: observed from the people, or given). Its
    # error moves every cue together (the feet's and the head's heights over the floor, and the network, which
    # reads the camera's height over it): a person's distance errs by its share of the drop from the camera to it.
    ankle_plane_sd_m: float = 0.0
    # A detector's mid-hips against a skeleton's pelvis (the truth's joint definition), per axis: nothing for
    # H36M-17 keypoints; ``body.DETECTOR_ROOT_DEFINITION_SD_M`` for a detector's.
    root_definition_sd_m: float = 0.0

    @classmethod
    def for_model(cls, document: dict, layout: str | Skeleton = H36M17, source: body.KeypointSource | None = None,
                  **changes) -> RefineConfig:
        """The defaults (measured on the shipped ``ray3d``) with what a checkpoint document's ``uncertainty``
        says of its own model (its distance errors by distance, what the cues leave of them), for keypoints of
        ``layout`` (a detector's ankle keypoint stands higher than the mocap's ankle joint, by its own amount, and
        the refined pose's lowest ankle, drawn part of the way to its ray, ``KeypointSource.pose_ankle_m`` over the
        floor; its hips stand higher too, so its size chain is shorter: ``body.keypoint_source``; its
        mid-hips are not a skeleton's pelvis; ``source`` says whose keypoints they are where the layout does not),
        and ``changes``."""
        measured = model_uncertainty(document)
        name = layout_skeleton(layout).name
        source = source or body.keypoint_source(name)
        measured.update(contact_ankle_height_m=source.pose_ankle_m, keypoint_ankle_height_m=source.planted_ankle_m,
                        keypoint_ankle_sd_m=source.planted_ankle_sd_m, body_size_m=source.body_size_m,
                        read_size_m=source.read_size_m, read_size_sd=source.read_size_sd)
        if name in DETECTOR_LAYOUTS:
            measured["root_definition_sd_m"] = body.DETECTOR_ROOT_DEFINITION_SD_M
        return cls(**{**measured, **changes})

    def network_bias_sd(self, distance: np.ndarray) -> np.ndarray:
        """(...) distances (m) -> (...) the relative sd of the network's distance error shared by a track."""
        at, sd = np.array(self.depth_bias_sd).T
        return np.interp(distance, at, sd)

    def network_frame_sd(self, distance: np.ndarray) -> np.ndarray:
        """(...) distances (m) -> (...) the relative sd of one frame's distance error about the track's."""
        return self.depth_sd[0] + self.depth_sd[1] * np.asarray(distance)


def model_uncertainty(document: dict) -> dict:
    """What a checkpoint document's ``uncertainty`` says of its model, checked field by field (``RefineConfig``'s
    ``UNCERTAINTY_FIELDS``; anything else there is information): ``depth_bias_sd`` pairs of (distance m, relative
    sd) in increasing distance, ``depth_sd`` (a, b) of a + b d, the others one number; one ``InputError``
    naming the field otherwise."""
    given = document.get("uncertainty", {}) if isinstance(document, dict) else {}
    if not isinstance(given, dict):
        raise InputError(f"checkpoint JSON: uncertainty: expected an object, got {type(given).__name__}")
    measured = {}
    for key in (k for k in UNCERTAINTY_FIELDS if k in given):
        values = numeric_array(given[key], f"checkpoint JSON: uncertainty: {key}")
        shaped = {"depth_bias_sd": values.ndim == 2 and values.shape[1:] == (2,), "depth_sd": values.shape == (2,)}
        if not shaped.get(key, values.ndim == 0) or not values.size or not np.isfinite(values).all() \
                or (values < 0).any():
            raise InputError(f"checkpoint JSON: uncertainty: {key}: expected {_SHAPE_TEXT[key]}")
        if key == "depth_bias_sd" and np.any(np.diff(values[:, 0]) <= 0):
            raise InputError(f"checkpoint JSON: uncertainty: {key}: the distances must increase")
        measured[key] = tuple(map(tuple, values.tolist())) if key == "depth_bias_sd" else \
            tuple(values.tolist()) if key == "depth_sd" else float(values)
    return measured


_SHAPE_TEXT = {"depth_bias_sd": "[distance m, relative sd] pairs of numbers >= 0",
               "depth_sd": "[a, b] (numbers >= 0)", "floor_offset_sd_m": "a number >= 0",
               "residual_distance_sd": "a number >= 0"}


@dataclasses.dataclass(frozen=True)
class Refinement:
    """What the refinement found for one track, frame by frame and as a whole."""

    scale: np.ndarray          # (T,) the factor each frame was moved by along its rays
    contact: np.ndarray        # (T,) whether the lowest ankle ended within two standard deviations of the floor
    floor_cue: np.ndarray      # (T,) whether the feet-on-the-floor term was used in that frame
    floor_height_m: np.ndarray  # (T,) the floor under the feet: the known floor where the floor term was
                                # used, else the network's estimate of where the feet rest (NaN: feet unseen)
    position_sd_m: np.ndarray  # (T, 2) the root's standard deviation along its ray and across it (per axis)
    cue_shares: np.ndarray     # (T, 4) how much of each frame's distance each of ``CUES`` gave (rows sum to 1)
    body_size_m: float         # the track's size chain
    stature_m: float           # the person's estimated stature (``ray3d.body.stature`` of the upright frames)
    stature_sd_m: float

    def summary(self) -> dict:
        """The track's record in world files: totals, and the per-frame contact state and cues."""
        return {"stature_m": round(self.stature_m, 4), "stature_sd_m": round(self.stature_sd_m, 4),
                "stature_interval_m": [round(self.stature_m - 2 * self.stature_sd_m, 4),
                                       round(self.stature_m + 2 * self.stature_sd_m, 4)],
                "body_size_m": round(self.body_size_m, 4),
                "median_scale": round(float(np.median(self.scale)), 4),
                "contact_fraction": round(float(self.contact.mean()), 4),
                "floor_cue_fraction": round(float(self.floor_cue.mean()), 4),
                "position_sd_m": round(float(np.median(self.position_sd_m[:, 0])), 4),
                "cue_shares": {cue: round(float(share), 4) for cue, share in zip(CUES, self.cue_shares.mean(axis=0))},
                "frames": {"contact": self.contact.astype(int).tolist(),
                           "floor_cue": self.floor_cue.astype(int).tolist(),
                           "cue": [CUES[k] for k in np.argmax(self.cue_shares, axis=1)],
                           "floor_height_m": [None if not np.isfinite(h) else round(float(h), 3)
                                              for h in self.floor_height_m]}}
