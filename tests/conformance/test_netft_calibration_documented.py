"""The emulated Net F/T's calibration pages and READCALINFO, read as public clients read them.

``/netftcalapi.xml``: root ``netftCalibration`` with ``calcpf``/``calcpt``
(ros2_net_ft_driver, two Rust and one Python client), ``calfu``/``caltu`` unit
codes (an EtherDAQ ROS 2 driver), ``scalfu``/``scaltu`` unit names, and
``calsn``, ``calpn``, ``caldt``, ``calmr`` (one third-party Axia client); ATI's
Java demo asks ``netftapi2.xml?index=N`` and ``netftcalapi.xml?index=N``. Each
field's source is in docs/netft.md. READCALINFO is built and read by hand.
"""

from __future__ import annotations

import socket
import urllib.error
import urllib.request
import xml.etree.ElementTree as ET

import pytest
from netft_documented import CALINFO_REPLY, READCALINFO_REQUEST, start_box

from forcelearn.emulators.netft import NetFtEmulator, NetFtModelParams

LBF_N = 4.4482216152605
LBF_IN_NM = 0.112984829027617
LBF_BOX = NetFtModelParams(counts_per_force=20_000, counts_per_torque=333_333,
                           force_unit="lbf", torque_unit="lbf-in",
                           ranges=(130.0, 130.0, 400.0, 10.0, 10.0, 10.0))
"""Not the factory values, so no test can pass on a default hard-coded somewhere."""


def page(box: NetFtEmulator, path: str) -> ET.Element:
    """GET ``path`` from the box's web server; the parsed root element."""
    url = f"http://{box.host}:{box.ports['http_port']}{path}"
    with urllib.request.urlopen(url, timeout=2.0) as answer:
        assert answer.status == 200
        return ET.fromstring(answer.read())


def fields(root: ET.Element) -> dict[str, str]:
    """Child element name -> text."""
    return {child.tag: (child.text or "") for child in root}


def read_calinfo(box: NetFtEmulator) -> tuple[int, ...]:
    """READCALINFO over TCP: header, force unit, torque unit, cpf, cpt, six scale factors."""
    with socket.create_connection((box.host, box.ports["tcp_port"]), timeout=2.0) as sock:
        sock.sendall(READCALINFO_REQUEST)
        data = b""
        while len(data) < CALINFO_REPLY.size:
            chunk = sock.recv(CALINFO_REPLY.size - len(data))
            assert chunk, "the box closed the connection mid-reply"
            data += chunk
    return CALINFO_REPLY.unpack(data)


def test_the_calibration_page_is_served_with_the_fields_clients_read() -> None:
    """GET /netftcalapi.xml: root netftCalibration, counts per unit and units of the box."""
    with start_box(model=LBF_BOX) as box:
        cal = fields(page(box, "/netftcalapi.xml"))
    assert {"calsn", "calpn", "caldt", "calfu", "caltu", "scalfu", "scaltu",
            "calcpf", "calcpt", "calmr"} <= set(cal)
    assert float(cal["calcpf"]) == 20_000 and float(cal["calcpt"]) == 333_333
    assert (cal["scalfu"], cal["scaltu"]) == ("lbf", "lbf-in")
    ranges = [float(v) for v in cal["calmr"].split(";")]
    si = [r * (LBF_N if i < 3 else LBF_IN_NM) for i, r in enumerate(ranges)]
    assert si == pytest.approx([130.0, 130.0, 400.0, 10.0, 10.0, 10.0], rel=1e-5)  # 6 digits


def test_the_root_element_is_netftcalibration() -> None:
    """Public drivers look the fields up under this root (FirstChildElement)."""
    with start_box() as box:
        assert page(box, "/netftcalapi.xml").tag == "netftCalibration"
        assert page(box, "/netftapi2.xml").tag == "netft"


def test_the_calibration_page_readcalinfo_and_netftapi2_agree() -> None:
    """One calibration, three ways to read it: the same counts and unit codes everywhere."""
    with start_box(model=LBF_BOX, rdt_buffer_size=7) as box:
        cal = fields(page(box, "/netftcalapi.xml"))
        cfg = fields(page(box, "/netftapi2.xml"))
        header, fu, tu, cpf, cpt, *_scales = read_calinfo(box)
    assert header == 0x1234
    assert (int(cal["calfu"]), int(cal["caltu"])) == (fu, tu) == (1, 1)  # lbf, lbf-in
    assert float(cal["calcpf"]) == float(cfg["cfgcpf"]) == cpf
    assert float(cal["calcpt"]) == float(cfg["cfgcpt"]) == cpt
    assert (cal["scalfu"], cal["scaltu"]) == (cfg["scfgfu"], cfg["scfgtu"])
    assert cfg["comrdtbsiz"] == "7"


def test_atis_demo_asks_the_pages_by_index() -> None:
    """ATI's Java demo: netftapi2.xml?index=0, then netftcalapi.xml?index=<cfgcalsel>.

    It reads setcfgsel, cfgcalsel, cfgcpf, cfgcpt and comrdtrate from the first page.
    """
    with start_box() as box:
        cfg = fields(page(box, "/netftapi2.xml?index=0"))
        assert {"setcfgsel", "cfgcalsel", "cfgcpf", "cfgcpt", "comrdtrate"} <= set(cfg)
        cal = fields(page(box, f"/netftcalapi.xml?index={cfg['cfgcalsel']}"))
        assert cal["calcpf"] == cfg["cfgcpf"]


def test_an_index_the_emulated_box_does_not_hold_is_404() -> None:
    """The emulated box holds one configuration and one calibration (a documented choice)."""
    with start_box() as box, pytest.raises(urllib.error.HTTPError, match="404"):
        page(box, "/netftcalapi.xml?index=1")


def test_runrate_is_the_internal_rate_and_comrdtrate_the_output_rate() -> None:
    """A live page of a box set to 100/s: ``<runrate>7000</runrate>``, ``<comrdtrate>100``."""
    with start_box(rdt_rate_hz=100) as box:
        cfg = fields(page(box, "/netftapi2.xml"))
    assert (float(cfg["runrate"]), float(cfg["comrdtrate"])) == (7000, 100)
