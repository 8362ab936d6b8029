"""netft/pyNetFT's client against the emulated box (skipped where pyNetFT is not installed).

A second opinion beside the document-built tests: a maintained public client
(`pip install pynetft`; not a forcelearn dependency) discovers the box over
``/netftapi2.xml``, streams RDT and biases, and its own health counters judge
the stream.
"""

from __future__ import annotations

import itertools

import pytest
from netft_documented import start_box

pynetft = pytest.importorskip("pynetft")


def test_pynetft_streams_and_biases_the_emulated_box() -> None:
    """Calibration found, 7 internal samples per record at 1000/s, no loss, bias to zero."""
    with start_box(contact_mm=8.0, rdt_rate_hz=1000) as box:
        config = pynetft.Config(sensor_host=box.host, rdt_port=box.ports["rdt_port"],
                                http_port=box.ports["http_port"])
        with pynetft.Client(config, queue_size=64) as client:
            loaded = [s for _, s in zip(range(20), client.samples(timeout=2.0), strict=False)]
            client.bias()
            assert box.wait_handled(2)  # start, then bias
            later = [s for _, s in zip(range(200), client.samples(timeout=2.0), strict=False)]
            health = client.health()
    cal = health.sensor_configuration.calibration
    assert (cal.counts_per_force_unit, cal.counts_per_torque_unit) == (1e6, 1e6)
    assert cal.torque_unit == pynetft.TorqueUnit.NEWTON_METER  # the page says "Nm"
    steps = {b.ft_sequence - a.ft_sequence for a, b in itertools.pairwise(loaded)}
    assert 7 in steps and all(step % 7 == 0 for step in steps)  # a queue drop skips 7s
    assert max(abs(v) for v in loaded[-1].wrench) > 1.0
    assert max(abs(v) for v in later[-1].wrench) < 1e-5
    assert (health.lost_count, health.malformed_count, health.ft_backward_count) == (0, 0, 0)
