"""Bounded fuzz of every decoder fed from outside: link, CAN, state file, TOML files.

Properties (checked by the ``check_*`` functions of ``forcelearn.tools.fuzz.targets``):
no exception outside forcelearn's tree, and nothing accepted that was not
sent or saved. The long run (>= 10^5 inputs per target) is documented in
docs/fuzzing.md.
"""

from __future__ import annotations

import random
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from forcelearn.tools.fuzz import targets as fuzz

EXAMPLES = sorted((Path(__file__).parents[3] / "examples").glob("*.toml"))
mutations = st.lists(
    st.tuples(st.integers(0, fuzz.MUTATION_KINDS - 1), st.integers(0, 1 << 20),
              st.integers(0, 1023)),
    min_size=1, max_size=4,
)
BOUNDED = settings(max_examples=150, deadline=None,
                   suppress_health_check=[HealthCheck.function_scoped_fixture])


@BOUNDED
@given(seed=st.integers(0, 2**32), edits=mutations, chunk=st.integers(1, 17))
def test_link_decoder(seed: int, edits: list[fuzz.Mutation], chunk: int) -> None:
    """Damaged reply streams: only sent payloads come out, only ProtocolError is raised."""
    sent = fuzz.random_replies(random.Random(seed))
    fuzz.check_link(sent, fuzz.apply_mutations(fuzz.link_stream(sent), edits), chunk)


@BOUNDED
@given(seed=st.integers(0, 2**32))
def test_can_codec_listener_and_pairing(seed: int) -> None:
    """Random and damaged CAN frames: round trips hold, samples equal received pairs."""
    fuzz.check_can(fuzz.random_can_frames(random.Random(seed)))


def test_the_link_check_catches_the_old_leading_zero_hole() -> None:
    """The property is not vacuous: an accepted foreign payload is reported."""
    with pytest.raises(fuzz.FuzzFailure, match="never sent"):
        fuzz.check_link([b"\x83\x01\x00\x00"], fuzz.link_stream([b"\x00\x83\x01\x00\x00"]))


@pytest.fixture(scope="module")
def cases(tmp_path_factory: pytest.TempPathFactory) -> dict[str, fuzz.FileCase]:
    """One good file per kind, saved once for the module."""
    folder = tmp_path_factory.mktemp("fuzz")
    return {
        "state": fuzz.state_case(folder),
        "calibration": fuzz.calibration_case(folder),
        **{f"config-{p.stem}": fuzz.config_case(folder, p) for p in EXAMPLES},
    }


@pytest.mark.parametrize("kind", ["state", "calibration"])
@settings(max_examples=120, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(edits=mutations)
def test_damaged_files_are_refused_or_identical(
    cases: dict[str, fuzz.FileCase], kind: str, edits: list[fuzz.Mutation]
) -> None:
    """A damaged state or calibration file loads as saved or raises the typed error."""
    case = cases[kind]
    fuzz.check_file(case, fuzz.apply_mutations(case.good, edits))


@settings(max_examples=150, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(which=st.integers(0, 100), edits=mutations)
def test_damaged_configs_raise_only_config_errors(
    cases: dict[str, fuzz.FileCase], which: int, edits: list[fuzz.Mutation]
) -> None:
    """Every example cell config, damaged: a value or a ConfigError, nothing else."""
    configs = [c for name, c in cases.items() if name.startswith("config-")]
    case = configs[which % len(configs)]
    fuzz.check_file(case, fuzz.apply_mutations(case.good, edits))


@settings(max_examples=150, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(which=st.integers(0, 100), seed=st.integers(0, 2**32))
def test_configs_with_odd_values_raise_only_config_errors(
    cases: dict[str, fuzz.FileCase], which: int, seed: int
) -> None:
    """Settings of another type, length or size (NaN, inf, a table...): ConfigError or a value."""
    configs = [c for name, c in cases.items() if name.startswith("config-")]
    case = configs[which % len(configs)]
    fuzz.check_file(case, fuzz.value_mutant(random.Random(seed), case.good))


@settings(max_examples=100, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(at=st.integers(0, 1 << 20), digit=st.integers(0, 9))
def test_calibration_digit_changes_never_load_a_different_value(
    cases: dict[str, fuzz.FileCase], at: int, digit: int
) -> None:
    """Any digit of the calibration file changed: refused, or (in a comment) harmless."""
    case = cases["calibration"]
    digits = [i for i, b in enumerate(case.good) if 0x30 <= b <= 0x39]
    fuzz.check_file(case, fuzz.apply_mutations(case.good, [(1, digits[at % len(digits)],
                                                            0x30 + digit)]))


def test_a_fuzzed_run_that_stops_with_forcelearns_message_counts_as_stopped(tmp_path: Path):
    """The runs target's check: a wrong [filter] sign stops at the probe's first press."""
    config = tmp_path / "cell.toml"
    config.write_text("[filter]\nsign = 1.0\n")
    assert fuzz.check_run(config, tmp_path / "run") == "stopped"
