"""Bounded runs of the socket fuzz targets (Net F/T, live server) and proof they can fail.

The long runs (>= 10^5 inputs per target) are commands in docs/fuzzing.md.
"""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from forcelearn.tools.fuzz import live as fuzz_live
from forcelearn.tools.fuzz import netft as fuzz_netft
from forcelearn.tools.fuzz import targets as fuzz
from forcelearn.tools.fuzz.box import ScriptedServer


@pytest.mark.parametrize(("target", "inputs"), [("netft-xml", 300), ("netft-http", 30),
                                                ("netft-tcp", 30), ("netft-rdt", 30),
                                                ("live-http", 60)])
def test_socket_targets_hold_on_a_bounded_run(target: str, inputs: int) -> None:
    """A short run of each target over loopback: no foreign exception, no hang."""
    tally = fuzz.Tally()
    module = fuzz_netft if target.startswith("netft") else fuzz_live
    module.run_target(target, random.Random(7), inputs, tally)
    assert tally.inputs >= inputs and not tally.failures, tally.failures


def test_the_xml_check_reports_a_foreign_exception(monkeypatch: pytest.MonkeyPatch) -> None:
    """The property is not vacuous: a parser raising ValueError is a FuzzFailure."""
    from forcelearn.drivers.netft import calibration

    def broken(body: bytes) -> object:
        raise ValueError("cannot convert float NaN to integer")

    monkeypatch.setattr(calibration, "parse_netftapi2", broken)
    with pytest.raises(fuzz.FuzzFailure, match="ValueError"):
        fuzz_netft.check_xml(b"<netft/>")


def test_the_http_check_reports_a_hang(monkeypatch: pytest.MonkeyPatch) -> None:
    """A read that ignores its deadline (as main's did) is reported as a hang."""
    from forcelearn.drivers.netft import calibration

    def slow(host: str, port: int, timeout_s: float) -> object:
        import time

        time.sleep(timeout_s + fuzz_netft.HANG_SLACK_S + 0.2)
        return None

    monkeypatch.setattr(fuzz_netft, "HANG_SLACK_S", 0.1)
    monkeypatch.setattr(calibration, "read_calibration_http", slow)
    with ScriptedServer() as server, pytest.raises(fuzz.FuzzFailure, match="hang"):
        fuzz_netft.check_http(server, b"", False, b"", "close")


def test_the_state_target_reaches_numpy_header_errors(tmp_path: Path) -> None:
    """Header mutants of an intact archive reach numpy's header parser (TokenError & co)."""
    import io
    import warnings

    import numpy as np

    from forcelearn.tools.fuzz.loaders import npz_header_mutant

    case = fuzz.state_header_case(tmp_path)
    rng = random.Random(1)
    kinds = set()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(100):
            data = npz_header_mutant(rng, case.good, lambda b: fuzz.apply_mutations(
                b, fuzz.random_mutations(rng)))
            try:
                with np.load(io.BytesIO(data), allow_pickle=False) as archive:
                    for key in archive.files:
                        archive[key]
            except Exception as exc:
                kinds.add(type(exc).__name__)
            assert fuzz.check_file(case, data) in ("accepted", "rejected")
    assert {"TokenError", "ValueError"} <= kinds
