"""The calibration page reader (``/netftcalapi.xml``), pure: the emulator's page and bad pages."""

from __future__ import annotations

import pytest

from forcelearn.drivers.netft.calibration import parse_netftapi2
from forcelearn.drivers.netft.calibration_page import parse_netftcalapi
from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.netft import NetFtEmulator, NetFtModelParams
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.errors import SensorProtocolError

PAGE = (b'<?xml version="1.0"?><netftCalibration><calsn>FT1</calsn>'
        b"<calfu>2</calfu><caltu>3</caltu><scalfu>N</scalfu><scaltu>Nm</scaltu>"
        b"<calcpf>1000000</calcpf><calcpt>1000</calcpt><calmr>330;330;990;30;30;30</calmr>"
        b"</netftCalibration>")


def test_a_page_as_the_box_spells_it() -> None:
    """Counts per unit, units as written (Nm), ranges in SI from calmr."""
    cal = parse_netftcalapi(PAGE)
    assert (cal.counts_per_force, cal.counts_per_torque) == (1_000_000, 1000)
    assert (cal.force_unit, cal.torque_unit) == ("N", "Nm")
    assert cal.si_per_count[3:] == pytest.approx([1e-3] * 3)
    assert cal.ranges_si == pytest.approx((330, 330, 990, 30, 30, 30))


def test_the_emulated_page_agrees_with_its_netftapi2() -> None:
    """Both pages of one emulated box give the same scale and ranges."""
    model = NetFtModelParams(counts_per_force=20_000, counts_per_torque=333_333,
                             force_unit="lbf", torque_unit="lbf-in")
    with NetFtEmulator(CellPhysics(), SimClock(), model=model, rdt_port=0, tcp_port=0) as emu:
        page, api = parse_netftcalapi(emu.netftcalapi_xml()), parse_netftapi2(emu.netftapi2_xml())
    assert page.si_per_count == pytest.approx(api.si_per_count)
    assert page.ranges_si == pytest.approx(api.ranges_si)


@pytest.mark.parametrize(("body", "says"), [
    (b"<netftCalibration><calcpf>1", "not XML"),
    (PAGE.replace(b"netftCalibration", b"netft"), "root"),
    (PAGE.replace(b"<calcpt>1000</calcpt>", b""), "no <calcpt>"),
    (PAGE.replace(b"<calcpt>1000</calcpt>", b"<calcpt>many</calcpt>"), "not numbers"),
    (PAGE.replace(b"<calcpt>1000</calcpt>", b"<calcpt>1;2</calcpt>"), "expected one"),
    (PAGE.replace(b"<calcpt>1000</calcpt>", b"<calcpt>0</calcpt>"), "counts"),
    (PAGE.replace(b"<scaltu>Nm</scaltu>", b"<scaltu>furlong</scaltu>"), "torque unit"),
])
def test_bad_pages_are_refused_with_what_is_wrong(body: bytes, says: str) -> None:
    """Every defect is a SensorProtocolError naming it."""
    with pytest.raises(SensorProtocolError, match=says):
        parse_netftcalapi(body)
