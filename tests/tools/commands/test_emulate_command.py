"""``forcelearn emulate`` in its own process, and ``forcelearn check`` in another reaching it."""

from __future__ import annotations

import os
import queue
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from forcelearn.site.config import load_cell_config
from forcelearn.tools.cli import main

STARTUP_S = 20.0
STOP_S = 30.0
"""Bound on a stopped emulator's exit: its cell closes in ~0.05 s, but the interpreter's
tear-down of ~1,200 modules (scipy's ~490, through filterpy) took 0.2-0.8 s at idle and
up to 5.6 s with 8 busy processes on 2 cores (measured 2026-12-04); 10 s failed in a
loaded clean-clone CI."""


class Emulator:
    """A ``forcelearn emulate`` subprocess whose stdout lines are read by a thread."""

    def __init__(self, *args: str) -> None:
        self.process = subprocess.Popen(
            [sys.executable, "-m", "forcelearn.tools.cli", "emulate", *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        self.lines: queue.Queue[str] = queue.Queue()
        self.seen: list[str] = []
        threading.Thread(target=self._pump, daemon=True).start()

    def _pump(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:  # ends when the process closes its stdout
            self.lines.put(line.rstrip("\n"))

    def wait_for(self, pattern: str, timeout_s: float) -> re.Match[str]:
        """Return the first new line matching ``pattern``; fail after ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while (left := deadline - time.monotonic()) > 0:
            try:
                line = self.lines.get(timeout=left)
            except queue.Empty:
                break
            self.seen.append(line)
            if match := re.search(pattern, line):
                return match
        pytest.fail(f"no line matching {pattern!r} within {timeout_s} s; got {self.seen}")

    def stop(self, sig: int = signal.SIGTERM) -> int:
        """Send ``sig``, wait (bounded) and return the exit status."""
        self.process.send_signal(sig)
        return self.process.wait(timeout=STOP_S)

    def kill(self) -> None:
        """Make sure the process is gone: terminate, then kill, waits bounded."""
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=STOP_S)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(timeout=STOP_S)
        if self.process.stdout is not None:
            self.process.stdout.close()


@pytest.fixture
def spawn(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Callable[..., Emulator]]:
    """Start emulators; every one is gone after the test, even when it fails.

    Each gets its own ``--link-dir`` unless the test names one, so parallel runs
    on one host never share the stable symlinks.
    """
    started: list[Emulator] = []

    def start(*args: str) -> Emulator:
        if "--link-dir" not in args:
            args = (*args, "--link-dir", str(tmp_path_factory.mktemp("links")))
        emulator = Emulator(*args)
        started.append(emulator)
        return emulator

    yield start
    for emulator in started:
        emulator.kill()


def test_check_in_another_process_reaches_the_emulated_cell_through_slcan(
    spawn: Callable[..., Emulator], tmp_path: Path
) -> None:
    """Emulate prints two ptys and writes a site config; check passes through them, no move."""
    site = tmp_path / "site.toml"
    emulator = spawn("--write-config", str(site), "--seed", "2")
    robot = emulator.wait_for(r"^robot link \(computer link, pty\): (\S+)$", STARTUP_S).group(1)
    slcan = emulator.wait_for(r"^JR3 sensor \(slcan CAN adapter.*\): (\S+)$", STARTUP_S).group(1)
    emulator.wait_for(r"^site config written to", STARTUP_S)
    config = load_cell_config(site)
    assert (config.robot.url, config.bus.interface, config.bus.channel) == (robot, "slcan", slcan)
    assert Path(robot).exists() and Path(slcan).exists()
    # a loaded host is no real sensor: allow it pauses (the 0.1 s watchdog failed this check in
    # a clean-clone CI at load 3.9), as the other cross-process tests here do
    site.write_text(site.read_text() + "\n[safety]\nstale_sensor_s = 10.0\n")

    env = {k: v for k, v in os.environ.items() if not k.startswith("CAN_")}  # real slcan open
    checked = subprocess.run(
        [sys.executable, "-m", "forcelearn.tools.cli", "check", "--config", str(site),
         "--seconds", "0.5"],
        capture_output=True, text=True, timeout=60, env=env,
    )
    assert checked.returncode == 0, checked.stdout + checked.stderr
    assert f"channel {slcan}" in checked.stdout
    assert "controller 'forcelearn S3 controller emulator'" in checked.stdout
    samples = int(re.search(r"(\d+) samples in", checked.stdout).group(1))  # type: ignore[union-attr]
    assert samples > 50

    assert emulator.stop(signal.SIGTERM) == 0
    summary = emulator.wait_for(r"stopping: (\d+) robot moves executed, (\d+) JR3 samples", 1.0)
    assert int(summary.group(1)) == 0
    assert int(summary.group(2)) >= samples
    assert not Path(robot).exists() and not Path(slcan).exists()  # ptys (and links) released


def test_ctrl_c_stops_the_emulator_cleanly(spawn: Callable[..., Emulator]) -> None:
    """SIGINT (Ctrl-C) ends the process with status 0 after releasing its ptys."""
    emulator = spawn()
    slcan = emulator.wait_for(r"^JR3 sensor .*: (\S+)$", STARTUP_S).group(1)
    emulator.wait_for(r'^channel = "', STARTUP_S)  # the snippet is printed: fully up
    assert emulator.stop(signal.SIGINT) == 0
    emulator.wait_for(r"stopping: 0 robot moves", 1.0)
    assert not Path(slcan).exists()


def test_emulate_prints_its_pid_and_stable_links_that_survive_a_restart(
    spawn: Callable[..., Emulator], tmp_path: Path
) -> None:
    """The PID is printed; a site config saved once still reaches a restarted cell."""
    links, site = tmp_path / "links", tmp_path / "site.toml"
    first = spawn("--link-dir", str(links), "--write-config", str(site))
    pid = int(first.wait_for(r"running, PID (\d+)", STARTUP_S).group(1))
    assert pid == first.process.pid
    robot = first.wait_for(r"^robot link \(computer link, pty\): (\S+)$", STARTUP_S).group(1)
    first.wait_for(r"^site config written to", STARTUP_S)
    assert robot == str(links / "robot")
    assert "sleep_after_open_s = 0.0" in site.read_text()
    assert first.stop(signal.SIGTERM) == 0
    assert not (links / "robot").exists()

    second = spawn("--link-dir", str(links))
    second.wait_for(r'^channel = "', STARTUP_S)
    config = load_cell_config(site)  # the file written by the first emulator
    assert Path(config.robot.url).exists() and Path(config.bus.channel).exists()
    # a loaded host is no real sensor: allow it pauses (the real cell's 0.1 s watchdog failed
    # this check at a load average of 16), as the other cross-process tests here do
    site.write_text(site.read_text() + "\n[safety]\nstale_sensor_s = 10.0\n")
    env = {k: v for k, v in os.environ.items() if not k.startswith("CAN_")}
    checked = subprocess.run(
        [sys.executable, "-m", "forcelearn.tools.cli", "check", "--config", str(site),
         "--seconds", "0.2"],
        capture_output=True, text=True, timeout=60, env=env,
    )
    assert checked.returncode == 0, checked.stdout + checked.stderr


def test_fresh_per_connection_makes_a_run_independent_of_a_check_before_it(
    spawn: Callable[..., Emulator],
    tmp_path: Path,
    configured_map_toml: str,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Run, check, run again on one emulator: the two runs' trials are identical.

    Without --fresh-per-connection the second run meets a worn sponge and a sensor
    further along its noise sequence, and its trials differ (the default, as on a
    real cell). The run and check commands run in this process (the emulator's own
    process is the point; a check in another process is the test above).
    """
    site = tmp_path / "site.toml"
    links = str(tmp_path / "links")  # its own stable links: no other emulator's can interfere
    emulator = spawn("--write-config", str(site), "--fresh-per-connection", "--link-dir", links)
    emulator.wait_for(r"^site config written to", STARTUP_S)
    for name in [k for k in os.environ if k.startswith("CAN_")]:
        monkeypatch.delenv(name)
    # the in-process cell's watchdog and timeouts, so a stall of this host cannot make a
    # driver re-ask; and a whole output map: no probe (the sessions' independence is the point)
    timeouts = "[robot]\nack_timeout_s = 10.0\nreply_timeout_s = 10.0\n"
    text = site.read_text().replace("[robot]\n", timeouts)
    site.write_text(text + "\n[safety]\nstale_sensor_s = 10.0\n\n" + configured_map_toml)

    def cli(*args: str) -> None:
        assert main(list(args)) == 0

    run = ("run", "--config", str(site), "--trials", "1", "--seed", "3", "--no-progress")
    cli(*run, "--out", str(tmp_path / "first"))
    cli("check", "--config", str(site), "--seconds", "0.1")
    cli(*run, "--out", str(tmp_path / "second"))
    first = (tmp_path / "first" / "trials.csv").read_text()
    assert first == (tmp_path / "second" / "trials.csv").read_text()
    assert emulator.stop(signal.SIGTERM) == 0
    emulator.wait_for(r"3 client sessions", 5.0)


@pytest.mark.long
def test_a_run_through_emulate_in_another_process_equals_the_in_process_run(
    spawn: Callable[..., Emulator], tmp_path: Path
) -> None:
    """The same seed gives the same trials with the cell in this process or in another.

    The emulate process speaks to the run over a pty and an slcan adapter pty
    instead of an in-process pty and virtual bus; simulated time is charged by
    the same rules on both, so the numbers are byte-identical.
    """
    site = tmp_path / "site.toml"
    emulator = spawn("--write-config", str(site), "--seed", "3", "--link-dir", str(tmp_path / "l"))
    emulator.wait_for(r"^site config written to", STARTUP_S)
    env = {k: v for k, v in os.environ.items() if not k.startswith("CAN_")}
    # the in-process cell's watchdog and timeouts, so a stall of this host cannot differ
    timeouts = "[robot]\nack_timeout_s = 10.0\nreply_timeout_s = 10.0\n"
    text = site.read_text().replace("[robot]\n", timeouts)
    site.write_text(text + "\n[safety]\nstale_sensor_s = 10.0\n")

    def run(*args: str, out: Path) -> str:
        done = subprocess.run(
            [sys.executable, "-m", "forcelearn.tools.cli", "run", *args, "--trials", "1",
             "--seed", "3",
             "--no-progress", "--out", str(out)],
            capture_output=True, text=True, timeout=300, env=env,
        )
        assert done.returncode == 0, done.stdout + done.stderr
        return (out / "trials.csv").read_text()

    remote = run("--config", str(site), out=tmp_path / "remote")
    local = run(out=tmp_path / "local")
    assert remote == local
    assert emulator.stop(signal.SIGTERM) == 0


def test_the_old_robot_spelling_link_still_serves_the_computer_link(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--robot link`` (before the kinds got one name each) warns and serves computer_link."""
    from forcelearn.tools.cli import build_parser
    from forcelearn.tools.commands import emulate

    argv = ["emulate", "--robot", "link", "--link-dir", str(tmp_path)]
    args = build_parser(argv).parse_args(argv)
    stop = threading.Event()
    stop.set()  # serve, print, stop at once
    assert emulate.run(args, stop) == 0
    captured = capsys.readouterr()
    assert "--robot link is deprecated; write --robot computer_link" in captured.err
    assert f"robot link (computer link, pty): {tmp_path / 'robot'}" in captured.out
