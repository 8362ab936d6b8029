"""The phase schedule, the hyperparameter dataclass and s(r̂)."""

import itertools

import pytest

from forcelearn.errors import ConfigError
from forcelearn.learning import Phase, PhaseSchedule, SRVParams, sigma_of_prediction


def test_switches_after_exactly_n_consecutive_successes() -> None:
    """The N-th consecutive success switches the phase, not the (N−1)-th."""
    schedule = PhaseSchedule(success_trials=10)
    for _ in range(9):
        assert not schedule.end_trial(True)
    assert schedule.phase is Phase.GENERALIZED
    assert schedule.end_trial(True)
    assert schedule.phase is Phase.SPECIALIZED
    assert schedule.switch_trial == 9


def test_a_failure_resets_the_count() -> None:
    """Nine successes, a failure, then ten more: the switch comes on trial index 19."""
    schedule = PhaseSchedule(success_trials=10)
    for _ in range(9):
        schedule.end_trial(True)
    schedule.end_trial(False)
    assert schedule.consecutive_successes == 0
    for _ in range(9):
        schedule.end_trial(True)
    assert schedule.phase is Phase.GENERALIZED
    schedule.end_trial(True)
    assert schedule.switch_trial == 19


def test_specialized_phase_is_final() -> None:
    """Failures after the switch never bring the generalized phase back."""
    schedule = PhaseSchedule(success_trials=1)
    schedule.end_trial(True)
    for _ in range(5):
        assert not schedule.end_trial(False)
    assert schedule.phase is Phase.SPECIALIZED


def test_defaults_are_the_papers_section_4_values() -> None:
    """α, β, γ, d and N default to §4's simulation."""
    p = SRVParams()
    assert (p.alpha_generalized, p.beta_generalized) == (0.5, 0.5)
    assert (p.alpha_specialized, p.beta_specialized) == (0.1, 0.5)
    assert p.gamma == 0.9
    assert p.extent == (5, 5)
    assert p.success_trials == 10
    assert p.alpha(Phase.SPECIALIZED) == 0.1
    assert p.beta(Phase.GENERALIZED) == 0.5


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("gamma", 1.0),
        ("gamma", 0.0),
        ("alpha_generalized", -0.1),
        ("success_trials", 0),
        ("sigma_min", 0.0),
        ("extent", (5, -1)),
    ],
)
def test_bad_parameters_name_the_field(field: str, value: object) -> None:
    """Each invalid value raises a ConfigError naming its field."""
    with pytest.raises(ConfigError, match=field):
        SRVParams(**{field: value})  # type: ignore[arg-type]


def test_round_trip_through_a_dict_and_unknown_keys() -> None:
    """to_dict/from_dict round-trip; an unknown key is named."""
    p = SRVParams(gamma=0.8, extent=(3,))
    assert SRVParams.from_dict(p.to_dict()) == p
    with pytest.raises(ConfigError, match="gama"):
        SRVParams.from_dict({"gama": 0.8})


def test_sigma_is_non_negative_and_monotone_in_prediction() -> None:
    """s(r̂) never decreases as r̂ grows and stays within [σ_min, σ_max]."""
    values = [sigma_of_prediction(r / 10, 0.05, 0.5) for r in range(-10, 30)]
    assert all(b >= a for a, b in itertools.pairwise(values))
    assert min(values) == 0.05 and max(values) == 0.5
    assert sigma_of_prediction(0.5, 0.05, 0.5) == pytest.approx(0.275)
