"""`forcelearn emulate --robot egm` / `--sensor netft` as their own process, reached by check/run.

`forcelearn check` and `forcelearn run` in another process reach it as a real cell.
"""

from __future__ import annotations

import json
import queue
import re
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from forcelearn.site.config import load_cell_config

STARTUP_S = 60.0
CLIENT_S = 300.0


class Emulator:
    """A ``forcelearn emulate`` subprocess; a thread reads its stdout lines."""

    def __init__(self, *args: str) -> None:
        self.process = subprocess.Popen(
            [sys.executable, "-m", "forcelearn.tools.cli", "emulate", *args],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        )
        self.lines: queue.Queue[str] = queue.Queue()
        self.seen: list[str] = []
        threading.Thread(target=self._pump, daemon=True).start()

    def _pump(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.lines.put(line.rstrip("\n"))

    def wait_for(self, pattern: str) -> re.Match[str]:
        """Return the first new line matching ``pattern`` (fail after STARTUP_S of silence)."""
        while True:
            try:
                line = self.lines.get(timeout=STARTUP_S)
            except queue.Empty:
                pytest.fail(f"no line matching {pattern!r}; got {self.seen}")
            self.seen.append(line)
            if match := re.search(pattern, line):
                return match

    def stop(self) -> int:
        """SIGTERM, then the exit status (bounded wait)."""
        self.process.send_signal(signal.SIGTERM)
        return self.process.wait(timeout=30)


def cli(*args: str) -> subprocess.CompletedProcess[str]:
    """Run a forcelearn command in a child process."""
    return subprocess.run(
        [sys.executable, "-m", "forcelearn.tools.cli", *args],
        capture_output=True, text=True, timeout=CLIENT_S, check=False,
    )


@pytest.mark.parametrize(
    ("options", "robot_line", "sensor_line"),
    [
        (("--robot", "egm"), r"robot EGM", r"JR3 sensor"),
        (("--sensor", "netft"), r"robot link", r"Net F/T sensor"),
    ],
)
def test_check_then_run_reach_the_emulate_process(
    tmp_path: Path, options: tuple[str, ...], robot_line: str, sensor_line: str,
    configured_map_toml: str,
) -> None:
    """The emulate process prints a site config; check passes (no move); a trial runs."""
    site = tmp_path / "site.toml"
    # its own stable links: parallel tests never share the default folder's
    emulator = Emulator(*options, "--write-config", str(site), "--link-dir", str(tmp_path / "l"))
    try:
        emulator.wait_for(robot_line)
        emulator.wait_for(sensor_line)
        emulator.wait_for("site config written")
        # a loaded CI host is no real sensor: allow it pauses (a real cell keeps 0.1 s), as
        # the in-process emulated cell does; a whole output map: the probe over EGM and
        # Net F/T is tested in-process (tests/site/test_cell_kinds.py)
        # four steps: the trial crosses the processes' wires in real time; its length is
        # not the point
        site.write_text(site.read_text() + "\n[safety]\nstale_sensor_s = 10.0\n\n"
                        + configured_map_toml + "steps_per_trial = 4\n")
        config = load_cell_config(site)
        assert not config.robot_emulated and not config.sensor_emulated
        if "egm" in options:
            assert config.robot_kind == "egm" and config.robot.lockstep
        else:
            assert config.sensor_kind == "netft" and config.sensor.host == "127.0.0.1"
        checked = cli("check", "--config", str(site), "--seconds", "0.2")
        assert checked.returncode == 0, checked.stdout + checked.stderr
        assert "the robot was not moved" in checked.stdout
        if "egm" in options:  # the controller it paired with, and nothing ignored
            assert "paired with the controller at ('127.0.0.1', " in checked.stdout
            assert "ignored: 0 from other hosts, 0 of the other RobotWare" in checked.stdout
        out = tmp_path / "run"
        ran = cli("run", "--config", str(site), "--trials", "1", "--out", str(out),
                  "--no-progress")
        assert ran.returncode == 0, ran.stdout + ran.stderr
        summary = json.loads((out / "summary.json").read_text())
        assert summary["trials"] == 1 and summary["steps"] > 0 and summary["cell_time_s"] > 0
    finally:
        code = emulator.stop()
    assert code == 0
    emulator.wait_for("forcelearn emulate: stopping")
