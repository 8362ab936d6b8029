"""EmulatedCell: client sessions see a fresh cell on request; the default remembers wear."""

from __future__ import annotations

from pathlib import Path

import pytest
import serial

from forcelearn.errors import ConfigError
from forcelearn.site.config import BusConfig, load_cell_config
from forcelearn.site.emulated_cell import EmulatedCell


def _open_session(cell: EmulatedCell) -> None:
    """Open the CAN channel as python-can's slcan does (``O``), and wait for its reply."""
    with serial.serial_for_url(cell.paths()["jr3-slcan"], timeout=5.0) as port:
        port.write(b"O\r")
        assert port.read_until(b"\r") == b"\r"  # the reply comes after the session hook ran
        port.write(b"C\r")
        assert port.read_until(b"\r") == b"\r"


@pytest.mark.parametrize("fresh", [False, True])
def test_sessions_start_fresh_only_when_asked(tmp_path: Path, fresh: bool) -> None:
    """Sponge wear carries over between sessions unless fresh_per_connection."""
    with EmulatedCell(load_cell_config(), link_dir=tmp_path, fresh_per_connection=fresh) as cell:
        _open_session(cell)
        start = cell.sponge.state_dict()
        cell.sponge.finish_pass()  # a client wore the sponge
        worn = cell.sponge.state_dict()
        assert worn != start
        _open_session(cell)
        assert cell.sessions == 2
        assert cell.sponge.state_dict() == (start if fresh else worn)
        assert Path(cell.paths()["jr3-slcan"]) == tmp_path / "jr3-slcan"
    assert not (tmp_path / "jr3-slcan").exists()


def test_slcan_open_delay_is_configurable_only_for_slcan() -> None:
    """sensor.sleep_after_open_s reaches python-can as sleep_after_open; refused elsewhere."""
    assert BusConfig("slcan", "/dev/ttyACM0", sleep_after_open_s=0.0).can_kwargs() == {
        "sleep_after_open": 0.0
    }
    assert BusConfig("slcan", "/dev/ttyACM0").can_kwargs() == {}
    with pytest.raises(ConfigError, match="sleep_after_open_s"):
        BusConfig("socketcan", "can0", sleep_after_open_s=0.0)
