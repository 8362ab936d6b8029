"""Many independent SRV learners stepped together: one set of numpy arrays for all members.

A *member* is one learner of :mod:`forcelearn.learning.srv` (one seed, one
:class:`SRVParams`); the batch holds ``B`` of them over the same box grid and
steps them in lockstep, so a study of many seeds pays Python's per-step
overhead once per batch step instead of once per member step.

Exactness: member ``b`` of a batch gives the same numbers, bit for bit, as an
:class:`SRVLearner` built with the same grid, params and seed, fed the same
inputs and evaluations (tests/learning/test_batched.py). For that:

* every member owns its ``numpy.random.Generator``; its normals are drawn in
  blocks (``Generator.standard_normal`` yields the same stream whether asked for
  2 values 100 times or 200 values once) and consumed in the single learner's
  order, 2 per exploring act. The generators therefore run ahead of what was
  consumed: a batch's generator state is not a resumable state (studies resume
  whole runs, docs/studies.md);
* the arithmetic of eqs. (1)-(3) is written in the single learner's order.

Layout: W is stored padded by ``D`` (the largest extent) on every side of the
grid, one flat row ``B · Π(P_i + 2D)`` long per output, so a neighbourhood is the
input box's flat index plus a fixed offset table and never needs clipping: the
pad absorbs the part of the block that lies outside the grid and is never read.
Members may differ in every :class:`SRVParams` field; a member with a smaller
extent gets zeros in its kernel outside its block (adding ±0.0 leaves values equal).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from forcelearn.errors import ConfigError
from forcelearn.learning.boxes import BoxGrid, BoxRangeError, neighbourhood_kernel
from forcelearn.learning.exploration import IdentityOutput, OutputMap
from forcelearn.learning.params import SRVParams
from forcelearn.learning.phase import Phase, PhaseSchedule
from forcelearn.learning.srv import SRVLearner

NORMAL_BLOCK = 4096
"""Normals drawn per member per refill (an even number: 2 per act for 2 outputs)."""


@dataclass(frozen=True)
class BatchAction:
    """What the acting members did at one batch step (arrays over those members)."""

    members: np.ndarray
    """Indices of the members that acted, shape (M,)."""
    box: np.ndarray
    """Flat (unpadded) box index per member, shape (M,)."""
    padded: np.ndarray
    """Index of each member's input box in the padded weight rows, shape (M,)."""
    prediction: np.ndarray
    """r̂ per member, shape (M,)."""
    sigma: np.ndarray
    """σ = s(r̂) per member, action units, shape (M,)."""
    mean: np.ndarray
    """μ, shape (M, n_outputs), action units."""
    action: np.ndarray
    """a ~ N(μ, σ), shape (M, n_outputs), action units."""
    output: np.ndarray
    """y(a, x), shape (M, n_outputs), device units."""


class BatchedSRVLearner:
    """``B`` SRV-over-BOXES learners on one grid, stepped together.

    Args:
        grid: the BOXES partition shared by all members.
        n_outputs: action components per box.
        params: one :class:`SRVParams` per member (its length is ``B``).
        seeds: one seed or ``numpy.random.Generator`` per member.
        output: the output map y(a, x), applied to (M, n_outputs) arrays at once.
    """

    def __init__(
        self,
        grid: BoxGrid,
        n_outputs: int,
        params: Sequence[SRVParams],
        seeds: Sequence[int | np.random.Generator],
        output: OutputMap | None = None,
    ):
        if len(params) != len(seeds) or not params:
            raise ConfigError(
                f"give one SRVParams per seed: got {len(params)} params and {len(seeds)} seeds"
            )
        for p in params:
            if len(p.extent) != grid.ndim:
                raise ConfigError(
                    f"extent {p.extent} has {len(p.extent)} entries; the grid has "
                    f"{grid.ndim} dimensions: give one extent d_i per dimension"
                )
        if n_outputs < 1:
            raise ConfigError(f"n_outputs must be >= 1, got {n_outputs}")
        self.grid = grid
        self.n_outputs = int(n_outputs)
        self.params = tuple(params)
        self.size = len(params)
        self.output: OutputMap = output or IdentityOutput()
        self.rngs = [
            s if isinstance(s, np.random.Generator) else np.random.default_rng(s) for s in seeds
        ]
        self.schedules = [
            PhaseSchedule(
                success_trials=p.success_trials,
                phase=Phase.GENERALIZED if p.generalized_phase else Phase.SPECIALIZED,
            )
            for p in params
        ]
        shape = grid.shape
        pad = tuple(max(p.extent[i] for p in params) for i in range(grid.ndim))
        self._pad = np.array(pad)
        self._padded_shape = tuple(n + 2 * d for n, d in zip(shape, pad, strict=True))
        n_padded = int(np.prod(self._padded_shape))
        self._n_padded = n_padded
        initial_mean = np.array([p.initial_mean for p in params])
        # One row per output: fancy updates on a 1-D row are several times faster
        # than on a (boxes, outputs) array.
        self._weights = np.tile(np.repeat(initial_mean, n_padded), (self.n_outputs, 1))
        initial_prediction = np.array([p.initial_prediction for p in params])
        self._predictions = np.repeat(initial_prediction, grid.n_boxes)
        # Flat offsets of the full (2D+1)^n block around a box in the padded grid.
        strides = np.cumprod((1, *self._padded_shape[:0:-1]))[::-1]
        axes = np.meshgrid(*[np.arange(-d, d + 1) for d in pad], indexing="ij")
        self._offsets = sum(a.ravel() * s for a, s in zip(axes, strides, strict=True))
        self._padded_strides = strides
        self._kernels = np.stack([self._member_kernel(p, pad) for p in params])
        self._lows = np.array([d.low for d in grid.dimensions])
        self._spans = np.array([d.high - d.low for d in grid.dimensions])
        self._parts = np.array(shape)
        self._grid_strides = np.cumprod((1, *shape[:0:-1]))[::-1]
        self._sigma_min = np.array([p.sigma_min for p in params])
        self._sigma_max = np.array([p.sigma_max for p in params])
        self._alpha = np.zeros(self.size)
        self._beta = np.zeros(self.size)
        self._generalized = np.zeros(self.size, dtype=bool)
        for b in range(self.size):
            self._set_phase(b)
        self._normals = np.empty((self.size, NORMAL_BLOCK))
        self._used = np.full(self.size, NORMAL_BLOCK)  # empty: refilled at the first draw

    @staticmethod
    def _member_kernel(p: SRVParams, pad: tuple[int, ...]) -> np.ndarray:
        kernel = np.zeros(tuple(2 * d + 1 for d in pad))
        inner = tuple(slice(d - e, d + e + 1) for d, e in zip(pad, p.extent, strict=True))
        kernel[inner] = neighbourhood_kernel(p.extent, p.gamma)
        kernel[tuple(pad)] = 0.0  # the input box follows eq. (2) instead
        return kernel.ravel()

    def _set_phase(self, b: int) -> None:
        phase = self.schedules[b].phase
        self._alpha[b] = self.params[b].alpha(phase)
        self._beta[b] = self.params[b].beta(phase)
        self._generalized[b] = phase is Phase.GENERALIZED

    @property
    def weights(self) -> np.ndarray:
        """W of every member, shape (B, *grid, n_outputs) (a copy without the pad)."""
        full = np.moveaxis(self._weights, 0, -1).reshape(
            self.size, *self._padded_shape, self.n_outputs
        )
        inner = tuple(slice(d, d + n) for d, n in zip(self._pad, self.grid.shape, strict=True))
        return full[(slice(None), *inner)].copy()

    @property
    def predictions(self) -> np.ndarray:
        """V of every member, shape (B, *grid) (a copy)."""
        return self._predictions.reshape(self.size, *self.grid.shape).copy()

    def member_weights(self, b: int) -> np.ndarray:
        """W of member ``b``, shape (*grid, n_outputs) (a copy; only that member is read)."""
        rows = self._weights[:, b * self._n_padded:(b + 1) * self._n_padded]
        padded = np.moveaxis(rows.reshape(self.n_outputs, *self._padded_shape), 0, -1)
        inner = tuple(slice(d, d + n) for d, n in zip(self._pad, self.grid.shape, strict=True))
        return padded[inner].copy()

    def member_predictions(self, b: int) -> np.ndarray:
        """V of member ``b``, shape grid (a copy)."""
        n = self.grid.n_boxes
        return self._predictions[b * n:(b + 1) * n].reshape(self.grid.shape).copy()

    def phase(self, member: int) -> Phase:
        """The learning phase in force for ``member``."""
        return self.schedules[member].phase

    def box_index(self, x: np.ndarray) -> np.ndarray:
        """Return the flat box of each input row of ``x`` (M, ndim), as BoxGrid.index does."""
        return self._box_indices(x) @ self._grid_strides

    def _box_indices(self, x: np.ndarray) -> np.ndarray:
        """Per-dimension box indices (M, ndim) of the inputs ``x``."""
        f = (x - self._lows) / self._spans
        outside = (f < 0.0) | (f > 1.0) | np.isnan(f)
        if outside.any():
            if self.grid.out_of_range == "error" or np.isnan(f).any():
                row, dim = np.argwhere(outside)[0]
                d = self.grid.dimensions[dim]
                raise BoxRangeError(
                    f"input {d.name}={float(x[row, dim])!r} is outside the partitioned range "
                    f"[{d.low}, {d.high}]; widen the range, or build the grid with "
                    "out_of_range='clamp' to use the edge box"
                )
            f = np.clip(f, 0.0, 1.0)
        boxes: np.ndarray = np.minimum((f * self._parts).astype(np.int64), self._parts - 1)
        return boxes

    def _draw(self, members: np.ndarray) -> np.ndarray:
        n = self.n_outputs
        empty = members[self._used[members] + n > NORMAL_BLOCK]
        for b in empty.tolist():
            left = self._normals[b, self._used[b] :].copy()
            fresh = self.rngs[b].standard_normal(NORMAL_BLOCK - left.size)
            self._normals[b] = np.concatenate([left, fresh])
            self._used[b] = 0
        columns = self._used[members][:, None] + np.arange(n)
        self._used[members] += n
        normals: np.ndarray = self._normals[members[:, None], columns]
        return normals

    def act(self, members: np.ndarray, x: np.ndarray, explore: bool = True) -> BatchAction:
        """Steps S3-S4 for ``members`` (indices) at inputs ``x`` (M, ndim).

        With ``explore=False`` the actions are the means μ and no normals are used.
        """
        members = np.asarray(members, dtype=np.int64)
        indices = self._box_indices(x)
        box = indices @ self._grid_strides
        padded = members * self._n_padded + (indices + self._pad) @ self._padded_strides
        r_hat = self._predictions[members * self.grid.n_boxes + box]
        clipped = np.clip(r_hat, 0.0, 1.0)
        smin, smax = self._sigma_min[members], self._sigma_max[members]
        sigma = smin + (smax - smin) * clipped
        mu = self._weights[:, padded].T
        a = mu + sigma[:, None] * self._draw(members) if explore else mu.copy()
        y = np.asarray(self.output(a, x), dtype=float)
        return BatchAction(members, box, padded, r_hat, sigma, mu, a, y)

    def learn(self, step: BatchAction, r: np.ndarray) -> None:
        """Steps S7-S8 for the members of ``step``: eq. (1), eq. (2), and eq. (3) if generalized."""
        r = np.asarray(r, dtype=float)
        if not np.isfinite(r).all():
            raise ValueError(f"evaluations r must be finite, got {r[~np.isfinite(r)][:3]!r}")
        members = step.members
        alpha = self._alpha[members]
        r_hat = step.prediction
        self._predictions[members * self.grid.n_boxes + step.box] += self._beta[members] * (
            r - r_hat
        )
        centre = step.padded
        gen = self._generalized[members]
        if gen.any():
            g = np.flatnonzero(gen)
            change = (alpha[g] * (r_hat[g] - r[g]))[:, None] * (step.action[g] - step.mean[g])
            block = centre[g][:, None] + self._offsets
            kernels = self._kernels[members[g]]
            for o, row in enumerate(self._weights):
                row[block] += kernels * change[:, o : o + 1]
        self._weights[:, centre] += (
            (alpha * (r_hat - r))[:, None] * (step.action - step.mean) / step.sigma[:, None]
        ).T

    def end_trial(self, member: int, success: bool) -> bool:
        """Record ``member``'s finished trial; True if its phase switched now."""
        switched = self.schedules[member].end_trial(success)
        if switched:
            self._set_phase(member)
        return switched

    def member(self, b: int, output: OutputMap | None = None) -> SRVLearner:
        """Return member ``b`` as a single :class:`SRVLearner` (copies of W, V and the phase).

        Its generator is a fresh one: use it for greedy (μ-only) evaluation or
        inspection, not to continue the member's random stream.
        """
        learner = SRVLearner(
            self.grid, self.n_outputs, self.params[b], rng=0, output=output or self.output
        )
        learner.weights[...] = self.member_weights(b)
        learner.predictions[...] = self.member_predictions(b)
        s = self.schedules[b]
        learner.schedule = PhaseSchedule(
            s.success_trials, s.phase, s.consecutive_successes, s.trials, s.switch_trial
        )
        return learner
