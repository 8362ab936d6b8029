"""The BOXES partition: index, range policy, neighbourhood slices and kernel."""

import math

import numpy as np
import pytest

from forcelearn.errors import ConfigError
from forcelearn.learning import BoxGrid, BoxRangeError, Dimension, neighbourhood_kernel


def paper_grid(policy: str = "error") -> BoxGrid:
    """The §4 partition: θ1 45±15° in 100 parts, θ2 −45±30° in 200 parts."""
    return BoxGrid(
        [Dimension("theta1_deg", 30.0, 60.0, 100), Dimension("theta2_deg", -75.0, -15.0, 200)],
        out_of_range=policy,  # type: ignore[arg-type]
    )


def test_paper_grid_has_20000_boxes() -> None:
    """100 x 200 parts make the paper's 20,000 boxes."""
    grid = paper_grid()
    assert grid.shape == (100, 200)
    assert grid.n_boxes == 20_000


@pytest.mark.parametrize(
    ("x", "expected"),
    [
        ((30.0, -75.0), (0, 0)),  # lower bounds belong to the first box
        ((30.2999, -74.7001), (0, 0)),  # just inside the first box (widths 0.3° and 0.3°)
        ((30.3000001, -74.6999999), (1, 1)),  # next box starts at low + width
        ((45.0, -45.0), (50, 100)),  # the start pose of §4
        ((60.0, -15.0), (99, 199)),  # upper bounds belong to the last box
        ((59.9999, -15.0001), (99, 199)),
    ],
)
def test_index_maps_inputs_to_the_right_box(x: tuple[float, float], expected: tuple) -> None:
    """Box index is floor((x - low) / width), the upper edge folded into the last box."""
    assert paper_grid().index(x) == expected


@pytest.mark.parametrize("x", [(29.99, -45.0), (45.0, -14.9), (61.0, -80.0)])
def test_outside_the_range_is_a_clear_error_by_default(x: tuple[float, float]) -> None:
    """An input outside the partition names the dimension instead of picking a wrong box."""
    with pytest.raises(BoxRangeError, match="outside the partitioned range"):
        paper_grid().index(x)


def test_clamp_policy_uses_the_nearest_edge_box() -> None:
    """With out_of_range='clamp' the nearest edge box is used on purpose."""
    grid = paper_grid("clamp")
    assert grid.index((10.0, 0.0)) == (0, 199)
    assert grid.index((99.0, -99.0)) == (99, 0)


def test_exact_boundaries_open_the_next_box() -> None:
    """On a grid with representable edges, each edge belongs to the box above it."""
    grid = BoxGrid([Dimension("y_mm", -4.0, 4.0, 8)])
    assert [grid.index((v,))[0] for v in (-4.0, -3.0, -0.5, 0.0, 3.0, 4.0)] == [0, 1, 3, 4, 7, 7]


def test_nan_is_an_error_even_when_clamping() -> None:
    """NaN has no nearest box."""
    with pytest.raises(BoxRangeError):
        paper_grid("clamp").index((math.nan, -45.0))


def test_wrong_input_length_is_rejected() -> None:
    """An input vector of the wrong length is a ValueError, not an index error later."""
    with pytest.raises(ValueError, match="2 dimensions"):
        paper_grid().index((45.0,))


def test_contains_and_centre_agree_with_index() -> None:
    """The centre of every box indexes back to that box."""
    grid = BoxGrid(
        [Dimension("a", -1.0, 1.0, 7), Dimension("b", 0.0, 3.0, 4), Dimension("c", 5, 6, 3)]
    )
    for box in np.ndindex(grid.shape):
        centre = grid.centre(box)
        assert grid.contains(centre)
        assert grid.index(centre) == box
    assert not grid.contains((1.5, 0.0, 5.5))


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"low": 1.0, "high": 1.0, "parts": 3}, "low < high"),
        ({"low": 0.0, "high": math.inf, "parts": 3}, "low < high"),
        ({"low": 0.0, "high": 1.0, "parts": 0}, "parts"),
    ],
)
def test_bad_dimensions_raise_config_errors(kwargs: dict, message: str) -> None:
    """A malformed dimension is rejected with a message that names it."""
    with pytest.raises(ConfigError, match=message):
        Dimension("theta", **kwargs)


def test_kernel_weights_are_gamma_to_the_city_block_distance() -> None:
    """Kernel entry at offset (i, j) is γ^(|i| + |j|)."""
    kernel = neighbourhood_kernel((5, 5), 0.9)
    assert kernel.shape == (11, 11)
    for i in range(-5, 6):
        for j in range(-5, 6):
            assert kernel[i + 5, j + 5] == pytest.approx(0.9 ** (abs(i) + abs(j)), rel=1e-15)


def test_neighbourhood_is_clipped_at_edges() -> None:
    """Near an edge the grid block and the kernel block shrink alike."""
    grid = paper_grid()
    grid_slices, kernel_slices = grid.neighbourhood((0, 197), (5, 5))
    assert grid_slices == (slice(0, 6), slice(192, 200))
    assert kernel_slices == (slice(5, 11), slice(0, 8))
