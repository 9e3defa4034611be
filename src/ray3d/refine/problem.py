"""The refinement's least-squares problem over a track: the factors each frame is moved by along its rays, the
track's body size, the network's shared error and the contact height, weighed by their uncertainties; solved by
Gauss-Newton with a robust loss, with its covariance and which cue carried each frame.

Two cues need no learning: the lowest ankle's ray meeting the floor (where the floor test holds), and, in upright
frames whose feet give no floor cue (hidden by a counter, below the picture), the head's ray meeting the height an
upright head of the track's size stands at (``body.HEAD_HEIGHT_OF_BODY_SIZE``)."""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse.linalg import splu

from ray3d.body import HEAD, HEAD_HEIGHT_OF_BODY_SIZE, body_sizes, lowest_ankles
from ray3d.geometry import Camera
from ray3d.geometry.floor import Floor
from ray3d.refine.config import CUES, EVIDENCE_FPS, PINNED_SD, UNCERTAINTY_SAMPLES, RefineConfig
from ray3d.refine.gauss_newton import gauss_newton, soft_l1_cost, soft_l1_weights

PRIORS = 4  # the rows of the track's terms' priors, last of the linear rows: size, network error, contact, head


def _term_columns(count: int) -> range:
    """x's columns of the track's terms, after the ``count`` frames' factors: size, network error, contact, head."""
    return range(count, count + PRIORS)


def _linear_terms(joints: np.ndarray, distance: np.ndarray, fps: float, config: RefineConfig, observed: np.ndarray,
                  per_frame: float) -> tuple[sparse.csr_matrix, np.ndarray, np.ndarray]:
    """The rows of the problem linear in x, their targets and their weights: each frame's factor against the
    network's (less its shared error), the smoothness of the (T,) camera ``distance``, each ``observed`` frame's
    size against the track's, and last the priors of the track's terms (``PRIORS`` rows)."""
    count = len(joints)
    columns = count + PRIORS
    size_column, bias_column, offset_column, head_column = _term_columns(count)
    blocks, targets, weights = [], [], []

    def add(matrix, target, weight) -> None:
        blocks.append(sparse.csr_matrix(matrix))
        targets.append(np.broadcast_to(target, matrix.shape[:1]))
        weights.append(np.broadcast_to(weight, matrix.shape[:1]))

    frames = sparse.eye(count, columns)
    add(frames - sparse.csr_matrix((np.ones(count), (np.arange(count), np.full(count, bias_column))),
                                   shape=(count, columns)),
        0.0, per_frame / config.network_frame_sd(distance))
    if count > 2:  # the distance log(s_t d_t) changes smoothly: its second difference is small
        second = sparse.csr_matrix(sparse.eye(count - 2, columns) - 2 * sparse.eye(count - 2, columns, 1)
                  + sparse.eye(count - 2, columns, 2))
        add(second, -(second[:, :count] @ np.log(distance)), 1 / (config.distance_acceleration_sd * fps ** -1.5))
    add(sparse.hstack([sparse.eye(count), -np.ones((count, 1)), sparse.csr_matrix((count, PRIORS - 1))]),
        -np.log(np.maximum(body_sizes(joints), 1e-3)), observed * per_frame / config.frame_size_sd)

    def prior(column: int, target: float, sd: float) -> None:
        add(sparse.csr_matrix(([1.0], ([0], [column])), shape=(1, columns)), target, 1 / sd)

    prior(size_column, np.log(config.body_size_m), config.body_size_sd)
    # The network's shared error and the person's contact height are held at 0 in the solution (weighing each
    # frame's network depth on its own and the contact height at its prior measured best on the test
    # performers, docs/RESULTS.md) and released to their spreads for its uncertainty.
    prior(bias_column, 0.0, PINNED_SD)
    prior(offset_column, 0.0, PINNED_SD)
    prior(head_column, 0.0, PINNED_SD)
    return sparse.vstack(blocks).tocsr(), np.concatenate(targets), np.concatenate(weights)


def _picks(frames: np.ndarray, column: np.ndarray | int, columns: int) -> sparse.csr_matrix:
    """One row per frame of ``frames``, a 1 in ``column`` (a frame's own, or one column for all) of ``columns``."""
    return sparse.csr_matrix((np.ones(len(frames)), (np.arange(len(frames)), np.broadcast_to(column, len(frames)))),
                             shape=(len(frames), columns))


class TrackProblem:
    """The least-squares problem over x = (log s_1..T, log S, b, f, h): the frames' factors, the track's size,
    the network's shared error, the person's contact height and their upright head's height against the prior's."""

    def __init__(self, joints: np.ndarray, camera: Camera, fps: float, config: RefineConfig, observed: np.ndarray,
                 floored: np.ndarray, floor: Floor, headed: np.ndarray):
        self.config, self.count, self.floor = config, len(joints), floor
        self.centre = camera.center
        distance = np.linalg.norm(joints[:, 0] - self.centre, axis=-1)
        self.ankle, self.head = lowest_ankles(joints), joints[:, HEAD]
        self.floored, self.headed = floored, headed
        # Neighbouring frames' errors are alike (the network sees overlapping windows), so a second of footage
        # is worth the same evidence at any frame rate; a frame filled in across a gap is no evidence of size.
        self.per_frame = np.sqrt(EVIDENCE_FPS / fps)
        self.columns = columns = self.count + PRIORS
        self.size_column, self.bias_column, self.offset_column, self.head_column = _term_columns(self.count)
        self.linear, self.target, self.weight = _linear_terms(joints, distance, fps, config, observed, self.per_frame)
        self.released = self.weight.copy()
        self.bias_sd = float(config.network_bias_sd(np.median(distance)))
        self.released[-3:] = 1 / np.array([self.bias_sd, config.floor_offset_sd_m, config.head_offset_sd_m])
        self.robust = np.ones(len(self.target) + floored.sum() + headed.sum(), dtype=bool)
        self.robust[len(self.target) - PRIORS:len(self.target)] = False
        floor_frames, head_frames = np.flatnonzero(floored), np.flatnonzero(headed)
        self.floor_scale_rows = _picks(floor_frames, floor_frames, columns)
        self.floor_offset_rows = _picks(floor_frames, self.offset_column, columns)
        self.head_scale_rows = _picks(head_frames, head_frames, columns)
        self.head_size_rows = _picks(head_frames, self.size_column, columns)
        self.head_offset_rows = _picks(head_frames, self.head_column, columns)

    def _moved(self, x: np.ndarray, points: np.ndarray, frames: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The ``frames``' factors, their (T, 3) ``points`` (lowest ankles, heads) moved by them, and the floor's
        height and gradient under the moved points."""
        scale = np.exp(x[:self.count][frames])
        moved = self.centre + scale[:, None] * (points[frames] - self.centre)
        height, gradient = self.floor.under_foot(moved[:, :2])
        return scale, moved, height, gradient

    def residuals(self, x: np.ndarray) -> np.ndarray:
        config = self.config
        _, feet, height, _ = self._moved(x, self.ankle, self.floored)
        above = feet[:, 2] - height - config.contact_ankle_height_m - x[self.offset_column]
        _, heads, under_heads, _ = self._moved(x, self.head, self.headed)
        head_height = (heads[:, 2] - under_heads - HEAD_HEIGHT_OF_BODY_SIZE * np.exp(x[self.size_column])
                       - x[self.head_column])
        return np.concatenate([self.weight * (self.linear @ x - self.target),
                               above * self.per_frame / config.ankle_height_sd_m,
                               head_height * self.per_frame / config.head_height_sd_m])

    def jacobian(self, x: np.ndarray) -> sparse.csr_matrix:
        def slopes(scale: np.ndarray, points: np.ndarray, gradient: np.ndarray) -> np.ndarray:
            """d(height over the floor) / d(log s) of points moved along their rays from the camera."""
            offset = points - self.centre
            return scale * (offset[:, 2] - np.einsum("ti,ti->t", gradient, offset[:, :2]))

        scale, _, _, gradient = self._moved(x, self.ankle, self.floored)
        slope = slopes(scale, self.ankle[self.floored], gradient)
        weight = self.per_frame / self.config.ankle_height_sd_m
        head_scale, _, _, head_gradient = self._moved(x, self.head, self.headed)
        head_slope = slopes(head_scale, self.head[self.headed], head_gradient)
        head_weight = self.per_frame / self.config.head_height_sd_m
        size = HEAD_HEIGHT_OF_BODY_SIZE * np.exp(x[self.size_column])
        return sparse.vstack([sparse.diags(self.weight) @ self.linear,
                              sparse.diags(slope * weight) @ self.floor_scale_rows - weight * self.floor_offset_rows,
                              sparse.diags(head_slope * head_weight) @ self.head_scale_rows
                              - head_weight * size * self.head_size_rows - head_weight * self.head_offset_rows])

    def cost(self, x: np.ndarray) -> float:
        """Robust (soft L1) for the frames' terms: quadratic within ``robust_scale`` standard deviations, linear
        beyond; squares for the priors of the track's size, network error and contact height, which would
        otherwise run away together."""
        return soft_l1_cost(self.residuals(x), self.robust, self.config.robust_scale)

    def _robust_weight(self, residuals: np.ndarray) -> np.ndarray:
        return soft_l1_weights(residuals, self.robust, self.config.robust_scale)

    def solve(self, start: np.ndarray, iterations: int = 50, tolerance: float = 1e-10) -> np.ndarray:
        """Gauss-Newton with iteratively reweighted least squares for the robust loss; each step is one sparse
        solve of the (banded) normal equations, so long tracks cost little."""
        return gauss_newton(self.residuals, self.jacobian, self.cost, self._robust_weight, start, iterations, tolerance)

    def cue_shares(self, x: np.ndarray) -> np.ndarray:
        """(T, 4) each frame's information on its distance (log s_t) from the network, the floor, the head's
        height and the body's size (``CUES``), robustly weighted at ``x``, as shares: which cues carried the frame's
        position. The network's and the size's are counted with what a track shares (the network's error, the person's
        size against the prior), which many frames do not average away."""
        config, count = self.config, self.count
        weight = self._robust_weight(self.residuals(x))
        rows = len(self.target)
        network, size = slice(0, count), slice(rows - PRIORS - count, rows - PRIORS)
        floors = slice(rows, rows + self.floored.sum())
        heads = slice(floors.stop, None)
        information = np.zeros((count, len(CUES)))
        information[:, CUES.index("network")] = weight[network] / (self.weight[network] ** -2 + self.bias_sd ** 2)
        frames = self.jacobian(x)[:, :count]
        squares = np.asarray(frames.multiply(frames).sum(axis=1)).ravel()
        information[self.floored, CUES.index("floor")] = weight[floors] * squares[floors]
        information[self.headed, CUES.index("head")] = weight[heads] * squares[heads]
        with np.errstate(divide="ignore"):
            information[:, CUES.index("size")] = weight[size] / (self.weight[size] ** -2 + config.body_size_sd ** 2)
        return information / np.maximum(information.sum(axis=1, keepdims=True), 1e-300)

    def standard_deviations(self, x: np.ndarray) -> tuple[np.ndarray, float]:
        """(T,) standard deviations of log s at every frame (evaluated at up to ``UNCERTAINTY_SAMPLES`` frames
        and interpolated between them) and that of log S, from the robustly weighted Gauss-Newton information,
        widened by how badly the feet fit the floor: the floor rows' mean squared residual in their standard
        deviations, where it exceeds 1 (lying, jumping, steps the floor does not know)."""
        residuals = self.residuals(x)
        weight = self._robust_weight(residuals)
        floor = residuals[len(self.target):len(self.target) + self.floored.sum()] / self.per_frame
        misfit = np.sqrt(max(1.0, float(np.mean(floor ** 2)))) if len(floor) else 1.0
        pinned, self.weight = self.weight, self.released
        jacobian = self.jacobian(x)
        self.weight = pinned
        information = (jacobian.T @ sparse.diags(weight) @ jacobian).tocsc() + sparse.eye(self.columns) * 1e-12
        lu = splu(information)
        frames = np.unique(np.linspace(0, self.count - 1, min(UNCERTAINTY_SAMPLES, self.count)).astype(int))
        wanted = np.append(frames, self.size_column)
        unit = np.zeros((self.columns, len(wanted)))
        unit[wanted, np.arange(len(wanted))] = 1.0
        variance = np.maximum(lu.solve(unit)[wanted, np.arange(len(wanted))], 0.0)
        sd = misfit * np.sqrt(variance)
        return np.interp(np.arange(self.count), frames, sd[:-1]), float(sd[-1])
