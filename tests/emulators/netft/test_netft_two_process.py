"""The emulator in a subprocess (``python -m forcelearn.emulators.netft``), the driver here."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator

import numpy as np
import pytest

from forcelearn.drivers.netft import NetFtConfig, NetFtSensor


@pytest.fixture()
def box() -> Iterator[dict]:
    """An emulated box in its own process, on free ports; stops when its stdin closes."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "forcelearn.emulators.netft", "--rdt-port", "0",
         "--tcp-port", "0", "--contact", "--seed", "5"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
    )
    try:
        line = proc.stdout.readline()
        assert line, "the emulator printed no ports"
        yield json.loads(line)
    finally:
        proc.stdin.close()  # the emulator's signal to stop
        try:
            assert proc.wait(timeout=20) == 0
        finally:
            proc.stdout.close()
            if proc.poll() is None:
                proc.kill()


@pytest.mark.parametrize("source", ["tcp", "http"])
def test_driver_reads_a_box_in_another_process(box: dict, source: str) -> None:
    """Ports printed as JSON on 127.0.0.1; calibration over TCP or HTTP; 2000 records in order."""
    assert box["host"] == "127.0.0.1"
    config = NetFtConfig(host=box["host"], rdt_port=box["rdt_port"], tcp_port=box["tcp_port"],
                         http_port=box["http_port"], calibration_source=source,
                         counts_per_force=1_000_000, stale_timeout_s=1.0)
    with NetFtSensor(config) as sensor:
        samples = sensor.read_many(2000)
        stats = sensor.stats
    assert [s.counter for s in samples] == list(range(2000))
    assert stats.lost == stats.duplicates == stats.out_of_order == 0
    fy = np.array([s.wrench[1] for s in samples])
    assert 5.0 < fy.mean() < 30.0  # the tool pressed into the sponge pushes back along +Y


def test_bench_netft_runs(capsys: pytest.CaptureFixture[str]) -> None:
    """``forcelearn bench netft`` runs a tiny configuration and prints both figures."""
    from forcelearn.tools.cli import main

    assert main(["bench", "netft", "--records", "300", "--seconds", "0.05",
                 "--repeats", "1"]) == 0
    out = capsys.readouterr().out
    assert "as fast as possible" in out and "p99" in out
