"""Counts per unit from the box's calibration page ``/netftcalapi.xml`` (pure parse).

A separate reader beside :mod:`.calibration` (which reads ``/netftapi2.xml``
and READCALINFO): the calibration page is what several public clients read
(root ``netftCalibration``; ``calcpf``, ``calcpt``, ``scalfu``, ``scaltu``,
``calmr``: sources in docs/netft.md, "The calibration pages"). Fetching it is
left to the caller (the HTTP read of :mod:`.calibration` does the same for
``/netftapi2.xml``); this module only turns the page's bytes into a checked
:class:`~.calibration.Calibration`.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

from forcelearn.drivers.netft.calibration import Calibration, check_calibration
from forcelearn.errors import SensorProtocolError
from forcelearn.protocols import netft as protocol

ROOT = "netftCalibration"


def parse_netftcalapi(xml: bytes) -> Calibration:
    """Parse ``/netftcalapi.xml`` into a checked :class:`Calibration` (units as the page says).

    Raises:
        SensorProtocolError: not XML, another root element, a field missing or not a
            number, or values :func:`check_calibration` refuses.
    """
    try:
        root = ET.fromstring(xml)
    except ET.ParseError as exc:
        raise SensorProtocolError(f"the Net F/T's netftcalapi.xml is not XML: {exc}") from exc
    if root.tag != ROOT:
        raise SensorProtocolError(
            f"the Net F/T's netftcalapi.xml has root <{root.tag}>, expected <{ROOT}>: "
            "is this the calibration page of a Net F/T?"
        )

    def text(tag: str) -> str:
        node = root.find(tag)
        if node is None or node.text is None or not node.text.strip():
            raise SensorProtocolError(f"the Net F/T's netftcalapi.xml has no <{tag}>")
        return node.text.strip()

    def numbers(tag: str) -> list[float]:
        raw = text(tag)
        try:
            return [float(v) for v in raw.split(";") if v.strip()]
        except ValueError as exc:
            raise SensorProtocolError(
                f"the Net F/T's netftcalapi.xml <{tag}> is {raw!r}, not numbers"
            ) from exc

    force_unit, torque_unit = text("scalfu"), text("scaltu")
    (cpf,), (cpt,) = _one(numbers("calcpf"), "calcpf"), _one(numbers("calcpt"), "calcpt")
    ranges_si = None
    if root.find("calmr") is not None and force_unit in protocol.FORCE_UNIT_SI and (
        torque_unit in protocol.TORQUE_UNIT_SI
    ):
        f_si = protocol.FORCE_UNIT_SI[force_unit]
        t_si = protocol.TORQUE_UNIT_SI[torque_unit]
        ranges_si = tuple(r * (f_si if i < 3 else t_si)
                          for i, r in enumerate(numbers("calmr")))
    return check_calibration(Calibration(cpf, cpt, force_unit, torque_unit,
                                         ranges_si=ranges_si, source="http"))


def _one(values: list[float], tag: str) -> list[float]:
    if len(values) != 1:
        raise SensorProtocolError(f"the Net F/T's netftcalapi.xml <{tag}> holds {len(values)} "
                                  "values, expected one")
    return values
