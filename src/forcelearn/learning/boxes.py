"""The BOXES associative memory: a regular partition of the input space.

Each input dimension ``i`` spans ``[low_i, high_i]`` and is split into ``parts_i``
equal intervals; the cross product of the intervals is the set of boxes
(Michie and Chambers; paper §3, Fig. 3). An input vector selects exactly one box.

Range policy: an input outside ``[low, high]`` is an error by default
(:class:`BoxRangeError`, which names the dimension and value), because silently
mapping it to an edge box would let the learner act on a state it has never
been trained for. A grid built with ``out_of_range="clamp"`` maps it to the
nearest edge box instead, on purpose. The upper bound itself belongs to the
last box. NaN is always an error.

The generalized-phase neighbourhood of a box is the block of boxes within
``d_i`` boxes along every dimension, clipped at the grid edges, each weighted
by ``gamma ** sum_i |d̂_i|`` (paper eq. 3).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from forcelearn.errors import ConfigError, ForcelearnError

RangePolicy = Literal["error", "clamp"]

InputVector = Sequence[float] | np.ndarray
"""An input: a sequence of floats or a 1-D array, one component per dimension."""


class BoxRangeError(ForcelearnError, ValueError):
    """An input lies outside the partitioned range and the grid does not clamp."""


@dataclass(frozen=True)
class Dimension:
    """One partitioned input dimension: ``parts`` equal intervals over ``[low, high]``."""

    name: str
    low: float
    high: float
    parts: int

    def __post_init__(self) -> None:
        if not (math.isfinite(self.low) and math.isfinite(self.high) and self.low < self.high):
            raise ConfigError(
                f"dimension {self.name!r}: need finite low < high, got [{self.low}, {self.high}]"
            )
        if int(self.parts) != self.parts or self.parts < 1:
            raise ConfigError(f"dimension {self.name!r}: parts must be an integer >= 1")

    @property
    def width(self) -> float:
        """Width of one interval, in the dimension's own unit."""
        return (self.high - self.low) / self.parts


class BoxGrid:
    """A BOXES partition over any number of input dimensions.

    Args:
        dimensions: the partitioned dimensions, in input-vector order.
        out_of_range: ``"error"`` (default) raises :class:`BoxRangeError` for an input
            outside the range; ``"clamp"`` maps it to the nearest edge box.
    """

    def __init__(self, dimensions: Sequence[Dimension], out_of_range: RangePolicy = "error"):
        if not dimensions:
            raise ConfigError("a BoxGrid needs at least one dimension")
        if out_of_range not in ("error", "clamp"):
            raise ConfigError(f"out_of_range must be 'error' or 'clamp', got {out_of_range!r}")
        self.dimensions: tuple[Dimension, ...] = tuple(dimensions)
        self.out_of_range: RangePolicy = out_of_range
        self.shape: tuple[int, ...] = tuple(int(d.parts) for d in self.dimensions)
        self._lows = [float(d.low) for d in self.dimensions]
        self._spans = [float(d.high - d.low) for d in self.dimensions]

    @property
    def ndim(self) -> int:
        """Number of input dimensions."""
        return len(self.shape)

    @property
    def n_boxes(self) -> int:
        """Total number of boxes."""
        return math.prod(self.shape)

    def contains(self, x: InputVector) -> bool:
        """True when every component of ``x`` lies within its dimension's range."""
        return all(d.low <= float(v) <= d.high for d, v in zip(self.dimensions, x, strict=True))

    def index(self, x: InputVector) -> tuple[int, ...]:
        """Return the box (one integer per dimension) that holds input ``x``."""
        if len(x) != self.ndim:
            raise ValueError(f"input has {len(x)} components, the grid has {self.ndim} dimensions")
        box = []
        for v, low, span, parts, dim in zip(
            x, self._lows, self._spans, self.shape, self.dimensions, strict=True
        ):
            f = (float(v) - low) / span
            if not 0.0 <= f <= 1.0:
                if math.isnan(f) or self.out_of_range == "error":
                    raise BoxRangeError(
                        f"input {dim.name}={float(v)!r} is outside the partitioned range "
                        f"[{dim.low}, {dim.high}]; widen the range, or build the grid with "
                        "out_of_range='clamp' to use the edge box"
                    )
                f = 0.0 if f < 0.0 else 1.0
            i = int(f * parts)
            box.append(i if i < parts else parts - 1)
        return tuple(box)

    def flat_index(self, box: Sequence[int]) -> int:
        """Return the row-major flat number of a box."""
        return int(np.ravel_multi_index(tuple(box), self.shape))

    def centre(self, box: Sequence[int]) -> np.ndarray:
        """Return the input value at the centre of a box."""
        return np.array(
            [d.low + (i + 0.5) * d.width for d, i in zip(self.dimensions, box, strict=True)]
        )

    def neighbourhood(
        self, box: Sequence[int], extent: Sequence[int]
    ) -> tuple[tuple[slice, ...], tuple[slice, ...]]:
        """Return the slices of the neighbourhood of ``box`` in the grid and in the kernel.

        The kernel is the ``(2 d_i + 1)``-wide block of :func:`neighbourhood_kernel`;
        near an edge both slices are clipped alike.
        """
        grid_slices = []
        kernel_slices = []
        for i, d, parts in zip(box, extent, self.shape, strict=True):
            lo = max(i - d, 0)
            hi = min(i + d + 1, parts)
            grid_slices.append(slice(lo, hi))
            kernel_slices.append(slice(lo - (i - d), hi - (i - d)))
        return tuple(grid_slices), tuple(kernel_slices)


def neighbourhood_kernel(extent: Sequence[int], gamma: float) -> np.ndarray:
    """Return the weights ``gamma ** sum_i |d̂_i|`` over the full neighbourhood block.

    The result has shape ``(2 d_1 + 1, ..., 2 d_n + 1)``; its centre (the input box)
    has weight 1.
    """
    distance = sum(np.meshgrid(*[np.abs(np.arange(-d, d + 1)) for d in extent], indexing="ij"))
    return np.power(float(gamma), distance)
