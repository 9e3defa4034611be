"""Track-level absolute refinement: where along its rays a lifted person stands, from three cues weighed by
their uncertainties, with the uncertainty of the answer.

The network's depth is good near the camera and poor far from it; a person's feet rest on the floor while
they stand or walk; and a person keeps one body size. Each frame is moved along the rays by one factor ``s_t``
about the camera centre (``X' = C + s_t (X - C)``), so its joints stay on their rays; the
factors, and one body size per track, are the least-squares solution of the terms below. Given the joints'
observed rays, the root ends on its observed ray, the limbs take the network's shape at the track's size, and each
measured joint then moves towards its own ray by as much as the keypoints are surer of where it is, across the
ray, than the network (``keypoint_error`` against ``pose_lateral_sd_m``): onto it for exact 2D, hardly at all
for a detector's keypoints of a person far away.

- the network: ``log s_t = b`` frame by frame, with a standard deviation that grows with the distance
  (``depth_sd``), where ``b`` is the network's error shared by the whole track;
- the floor: in every frame the detector saw, the lowest ankle lies ``contact_ankle_height_m + f`` above the
  floor under it (``ray3d.geometry.floor``: z = 0, or a declared region, felt over a foot's length), under a
  robust loss, so the frames where no foot touches it (jumps, a foot on a step) cost little; ``f`` is where the
  person's pelvis rests over the floor against the prior, shared by the track;
- the body: ``s_t`` times the frame's body size equals the track's size, which has an adult prior;
- smoothness: the person's distance changes smoothly (the second difference of its log is small), so the
  network's frame-to-frame depth jitter is smoothed away while a steady approach or retreat costs nothing.

Before solving, the floor is put to a test: over every stretch of ``agreement_window_s`` the distance at which
the feet would rest on the floor is compared with the network's; where they differ by more than
``agreement_sigmas`` of their joint uncertainty (a platform, stairs, a bed, a person on a vehicle) the floor
term is dropped for that stretch and the floor's height there is estimated from the network instead
(``ray3d.contact``). The frames in contact are those the solution puts within two standard deviations of the
floor. ``b`` and ``f`` are held at 0 in the solution (each frame's network depth weighed on its own, the contact
height at its prior: measured best on the test performers) and released to their spreads (``depth_bias_sd``: the
network's distance errors of one person are alike from frame to frame, so many frames do not average them away;
``floor_offset_sd_m``) for the answer's uncertainty: the solution's Gauss-Newton covariance, plus the share of the
distance the cues leave (``residual_distance_sd``), is the root's standard deviation along its ray per frame;
across it, a share of the keypoints' error. (A contact call from the ankles' speed was tried first: with
detector jitter on people 100 px tall it found one planted foot in ten frames; docs/RESULTS.md.) Heights and
sizes come from the training performers of the shipped mocap.
"""

from ray3d.refine.ankle_plane import AnklePlane, given_ankle_plane, observe_ankle_plane, size_evidence
from ray3d.refine.config import CUES, UNCERTAINTY_FIELDS, RefineConfig, Refinement
from ray3d.refine.track import joint_directions, network_position_sd, on_observed_rays, refine_track, scale_about

__all__ = ["CUES", "UNCERTAINTY_FIELDS", "AnklePlane", "RefineConfig", "Refinement", "given_ankle_plane",
           "joint_directions", "network_position_sd", "observe_ankle_plane", "on_observed_rays", "refine_track",
           "scale_about", "size_evidence"]
