"""The Surface-v0 digest is a function of the run: the same run hashes alike, another not."""

from __future__ import annotations

from forcelearn.tools.benchmarks.surface_digest import digest


def test_the_digest_repeats_and_tells_runs_apart() -> None:
    """Two short runs with one seed agree; another seed gives another digest."""
    first = digest(seed=3, zero_steps=4, random_steps=4)
    assert len(first) == 64
    assert digest(seed=3, zero_steps=4, random_steps=4) == first
    assert digest(seed=4, zero_steps=4, random_steps=4) != first
