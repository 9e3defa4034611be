"""Whether the floor is where a person's feet are: the feet-on-the-floor cue of the refinement
(``ray3d.refine``) tested, stretch by stretch, against the network's own depth."""

from __future__ import annotations

import numpy as np

from ray3d import body
from ray3d.body import body_sizes, lowest_ankles
from ray3d.geometry import Camera
from ray3d.geometry.floor import FLAT_FLOOR, Floor


def floor_agreement(joints: np.ndarray, camera: Camera, fps: float, candidates: np.ndarray, config,
                    floor: Floor = FLAT_FLOOR) -> tuple[np.ndarray, np.ndarray]:
    """Where the floor holds: (T, 17, 3) joints at the network's distances, the (T,) ``candidates`` frames
    whose feet were seen, a ``ray3d.refine.RefineConfig`` -> (T,) whether the floor cue agrees with the network
    and the body-size cue over the stretch around each frame, and (T,) the height of the floor the feet rest on
    over that stretch by the network's distances (the median lowest ankle less ``contact_ankle_height_m``; NaN
    where no candidate frame is near).

    A planted foot puts the lowest ankle ``contact_ankle_height_m`` above the floor; the factor that does so
    differs from 1 by the network's distance error, whose sd over a stretch is mostly the track's shared error,
    plus the person's own contact height. A stretch whose median factor is further from 1 than
    ``agreement_sigmas`` of that is a floor that is not where the feet are, unless
    - the body's size sides with the floor: at the floor's distance the person is nearer an adult's size than at
      the network's, by ``size_cue_margin`` (a network that is wrong about the distance is wrong about the size
      by the same factor; a raised floor leaves the size as the network sees it);
    - the feet would then rest more than ``largest_floor_step_m`` off the floor (the network is the one wrong);
    - the network's distance error puts the floor's height no better than ``floor_test_resolution_m`` (far
      away, or seen from near the floor's height): there the floor is believed, as the network cannot say
      otherwise;
    - or the feet are on a declared floor region: the user's knowledge of the scene is believed.
    """
    centre = camera.center
    ankle = lowest_ankles(joints)
    under = floor.height(ankle[:, :2])
    above = centre[2] - ankle[:, 2]
    wanted = centre[2] - under - config.contact_ankle_height_m
    valid = candidates & (above > 0.05) & (wanted > 0.05)
    half = max(1, int(round(config.agreement_window_s * fps / 2)))
    distance = np.linalg.norm(joints[:, 0] - centre, axis=-1)
    # A jump (or a foot on a step): the lowest ankle well over where the stretch's feet rest, by more than the
    # network's frame-to-frame depth noise can lift it, is not on the floor; pulled down to it, the person would be
    # pushed along the ray (CMU 02_04's jump: 0.3-0.4 m too far).
    rise = ankle[:, 2] - config.contact_ankle_height_m - _running_nanmedian(
        np.where(valid, ankle[:, 2] - config.contact_ankle_height_m, np.nan), half)
    valid &= ~(rise > np.maximum(body.AIRBORNE_ANKLE_M, 3 * config.network_frame_sd(distance) * above))
    factor, resting = np.full(len(joints), np.nan), np.full(len(joints), np.nan)
    factor[valid] = np.log(wanted[valid] / above[valid])
    resting[valid] = ankle[valid, 2] - config.contact_ankle_height_m
    stretch = _running_nanmedian(factor, half)
    spread = np.hypot(config.network_bias_sd(distance),
                      config.contact_height_sd_m / np.maximum(wanted, 0.05))
    resting = _running_nanmedian(resting, half)
    # log(adult size / the size at the network's distance), over the stretch: the size cue's own factor.
    sized = _running_nanmedian(np.where(valid, np.log(config.body_size_m / np.maximum(body_sizes(joints), 1e-3)),
                                        np.nan), half)
    size_sides_with_floor = np.abs(sized - stretch) + config.size_cue_margin <= np.abs(sized)
    believable = np.abs(resting - under) <= config.largest_floor_step_m
    testable = config.network_bias_sd(distance) * wanted <= config.floor_test_resolution_m
    declared = floor.region_index(ankle[:, :2]) >= 0  # the user's knowledge of the scene is not second-guessed
    agrees = valid & ((np.abs(stretch) <= config.agreement_sigmas * spread) | size_sides_with_floor
                      | ~believable | ~testable | declared)
    return agrees, resting


def _running_nanmedian(values: np.ndarray, half: int) -> np.ndarray:
    """(T,) -> (T,) the median of the finite values within ``half`` frames either side (NaN where none)."""
    padded = np.pad(values, half, constant_values=np.nan)
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1)
    out = np.full(len(values), np.nan)
    some = np.isfinite(windows).any(axis=1)
    out[some] = np.nanmedian(windows[some], axis=1)
    return out
