"""Calibration parsing: units into SI, and nonsense values refused with SensorProtocolError."""

from __future__ import annotations

import numpy as np
import pytest

from forcelearn.drivers.netft.calibration import from_calinfo, parse_netftapi2
from forcelearn.errors import SensorError, SensorProtocolError
from forcelearn.protocols.netft import CalInfo


def xml(**fields: str) -> bytes:
    """A netftapi2.xml body with sane defaults overridden by ``fields``."""
    base = {"cfgcpf": "1000000", "cfgcpt": "1000", "scfgfu": "N", "scfgtu": "N-mm",
            "comrdtrate": "7000", "setuserfilter": "4", "cfgmr": "130;130;400;10000;10000;10000"}
    base.update(fields)
    inner = "".join(f"<{k}>{v}</{k}>" for k, v in base.items() if v != "<absent>")
    return f"<?xml version='1.0'?><netft>{inner}</netft>".encode()


def test_http_fields_into_si() -> None:
    """N-mm torque: 1000 counts per N-mm is 1e6 counts per N·m; ranges come out in N·m."""
    cal = parse_netftapi2(xml())
    assert np.allclose(cal.si_per_count, [1e-6] * 3 + [1e-6] * 3)
    assert cal.rdt_rate_hz == 7000 and cal.filter_index == 4
    assert cal.ranges_si == pytest.approx((130, 130, 400, 10, 10, 10))
    lbf = parse_netftapi2(xml(scfgfu="lbf", cfgcpf="1000000"))
    assert lbf.si_per_count[0] == pytest.approx(4.4482216152605e-6)


@pytest.mark.parametrize(
    ("fields", "words"),
    [
        ({"cfgcpf": "0"}, "counts_per_force"),
        ({"cfgcpt": "-1000000"}, "counts_per_torque"),
        ({"cfgcpf": "nan"}, "counts_per_force"),
        ({"cfgcpf": "1e12"}, "counts_per_force"),
        ({"cfgcpf": "lots"}, "not a number"),
        ({"scfgfu": "furlong"}, "force unit"),
        ({"scfgtu": "<absent>"}, "no <scfgtu>"),
        ({"comrdtrate": "0"}, "RDT rate"),
        ({"cfgmr": "1;2;3"}, "ranges"),
    ],
)
def test_nonsense_from_http_is_refused(fields: dict[str, str], words: str) -> None:
    """Each implausible value is refused, and the message says which."""
    with pytest.raises(SensorProtocolError, match=words):
        parse_netftapi2(xml(**fields))


def test_nonsense_from_tcp_and_non_xml_are_refused() -> None:
    """Zero counts per unit or an unknown unit code over TCP; HTML instead of XML over HTTP."""
    with pytest.raises(SensorProtocolError, match=r"counts_per_force = 0\.0"):
        from_calinfo(CalInfo(2, 3, 0, 1_000_000))
    with pytest.raises(SensorProtocolError, match="unit codes"):
        from_calinfo(CalInfo(9, 3, 1_000_000, 1_000_000))
    with pytest.raises(SensorError, match="not XML"):
        parse_netftapi2(b"<html><body>login")
