"""Figure: one control step of the §5 task on the emulated cell's clock.

Runs the default emulated cell to the start of a trial, then records one step
(move, wait for in-position, settle, burst of samples) as the emulators spend
it: the bytes on each direction of the serial line, the frames on the CAN
bus, the tool's motion, the samples. Run
``python -m forcelearn.tools.figures.step_timeline [--out PATH]``; writes
``docs/results/step_timeline.png`` and prints the step's time budget.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from forcelearn.emulators.clock import Wire
from forcelearn.emulators.computer_link.server import ComputerLinkEmulator
from forcelearn.emulators.jr3.node import Jr3EmulatorNode
from forcelearn.site import CellSession, load_cell_config
from forcelearn.tasks.surface import SurfaceTask

DEFAULT_OUT = Path("docs/results/step_timeline.png")


def _logging(wire: Wire, log: list[tuple[float, float]]) -> None:
    """Record every transmission on ``wire`` as (start, end)."""
    transmit: Callable[..., tuple[float, float]] = wire.transmit

    def logged(duration_s: float, ready_s: float | None = None) -> tuple[float, float]:
        start, end = transmit(duration_s, ready_s)
        log.append((start, end))
        return start, end

    wire.transmit = logged  # type: ignore[method-assign]


def record_step(seed: int = 0) -> dict[str, Any]:
    """Run to the first step of a trial and record that step's timeline (simulated s)."""
    config = load_cell_config()
    with CellSession(config, seed=seed) as session:
        assert session.cell is not None and session.robot_emulator is not None
        assert session.sensor_emulator is not None and session.physics is not None
        task = SurfaceTask(session.cell, config.task, config.safety.max_step_mm)
        task.reset()
        robot_emulator: ComputerLinkEmulator = session.robot_emulator
        node: Jr3EmulatorNode = session.sensor_emulator
        engine = robot_emulator.engine
        physics = session.physics
        logs: dict[str, Any] = {"pc_to_robot": [], "robot_to_pc": [], "can": [], "samples": []}
        _logging(engine.rx_wire, logs["pc_to_robot"])
        _logging(engine.tx_wire, logs["robot_to_pc"])
        _logging(node.bus_wire, logs["can"])
        motion: list[tuple[float, float, float]] = []
        # A motion tick records the tool through CellPhysics._move_tool (set_pose is for tests),
        # so the tool's path is read there: (time, y, z) after each tick that moved it.
        move_tool = physics._move_tool

        def logged_move(key: Any) -> None:
            move_tool(key)
            assert physics.motion is not None
            motion.append((physics.motion.time_s, key[1], key[2]))

        physics._move_tool = logged_move  # type: ignore[method-assign]
        emit = node._emit_sample

        def logged_emit() -> None:  # each sample the node sends, at its time on the bus
            logs["samples"].append(node.clock.now_s)
            emit()

        node._emit_sample = logged_emit  # type: ignore[method-assign]
        start = physics.clock.now_s
        outcome = task.step(np.array([-8.0]))  # Y command (mm) near the desired force
        end = physics.clock.now_s
        logs.update(start_s=start, end_s=end, motion=list(motion), force_n=outcome.force_n)
        for key in ("pc_to_robot", "robot_to_pc", "can"):  # not the STOP of closing
            logs[key] = [span for span in logs[key] if span[0] < end]
        return logs


def plot(logs: dict[str, Any], out: Path) -> Path:
    """Draw the step: wire occupancy rows, the tool's Y and Z, the samples."""
    t0 = logs["start_s"]
    fig = Figure(figsize=(10, 5))
    FigureCanvasAgg(fig)
    wires, motion_ax = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": (1, 1.4)})
    rows = (
        ("PC → robot (9600 baud)", "pc_to_robot", "tab:blue"),
        ("robot → PC", "robot_to_pc", "tab:orange"),
        ("CAN bus (1 Mbit/s)", "can", "tab:green"),
    )
    for k, (_label, key, colour) in enumerate(rows):
        spans = [((a - t0) * 1e3, (b - a) * 1e3) for a, b in logs[key]]
        wires.broken_barh(spans, (k - 0.35, 0.7), color=colour)
    wires.set_yticks(range(len(rows)), [r[0] for r in rows])
    wires.set_title(
        f"one §5 control step on the emulated cell's clock: {1e3 * (logs['end_s'] - t0):.0f} ms "
        f"(move accepted, polls until in position, {len(logs['samples'])}-sample burst)",
        fontsize=10,
    )
    if logs["motion"]:
        t, y, z = (np.array(c) for c in zip(*logs["motion"], strict=True))
        motion_ax.plot((t - t0) * 1e3, y - y[0], label="tool Y − start (mm)")
        motion_ax.plot((t - t0) * 1e3, z - z[0], label="tool Z − start (mm)")
    for s in logs["samples"]:
        motion_ax.axvline((s - t0) * 1e3, color="tab:green", lw=0.3, alpha=0.5)
    motion_ax.set_xlabel("time since the step began (ms, simulated)")
    motion_ax.set_ylabel("mm")
    motion_ax.legend(fontsize=8, loc="center right")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    return out


def budget(logs: dict[str, Any]) -> str:
    """The step's time budget in words."""
    t0, end = logs["start_s"], logs["end_s"]
    link = sum(b - a for a, b in logs["pc_to_robot"]) + sum(b - a for a, b in logs["robot_to_pc"])
    can = sum(b - a for a, b in logs["can"])
    moving = [m[0] for m in logs["motion"]]
    first_motion = (moving[0] - t0) if moving else float("nan")
    last_motion = (moving[-1] - t0) if moving else float("nan")
    burst = (logs["samples"][-1] - logs["samples"][0]) if logs["samples"] else 0.0
    char_s = 10 / 9600
    polls = sum(1 for a, b in logs["pc_to_robot"] if b - a > 2.5 * char_s) - 1  # not the ACKs
    return (
        f"step {1e3 * (end - t0):.0f} ms: tool moves from {1e3 * first_motion:.0f} to "
        f"{1e3 * last_motion:.0f} ms; serial line busy {1e3 * link:.0f} ms over "
        f"{polls + 1} PC frames (MOVE_TO + {polls} status polls); CAN busy {1e3 * can:.1f} ms; "
        f"burst {len(logs['samples'])} samples over {1e3 * burst:.1f} ms"
    )


def main(argv: list[str] | None = None) -> int:
    """Record one step, print its budget, draw the figure."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = parser.parse_args(argv)
    logs = record_step()
    print(budget(logs))
    print(f"figure: {plot(logs, args.out)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
