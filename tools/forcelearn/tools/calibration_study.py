"""Calibration proven on tools drawn at random: ``python -m forcelearn.tools.calibration_study``.

For each of ``--tools`` tools drawn from ``--seed`` (docs/calibration.md, "Random tools"):

* mass log-uniform in 0.1..15 kg; centre of mass up to 200 mm off the sensor's
  axis (radius uniform 0..200 mm, any azimuth) and 0..250 mm along it; contact
  point 150..300 mm along the axis; mounting a uniformly random rotation;
* the emulated sensor of the cell (JR3 or Net F/T): the default model, or, when
  the tool's weight or gravity moment needs more, the same model with full
  scales, noise and drift all scaled up by one factor (a larger sensor of the
  same family: 1.25 x the load at 0.9 x full scale);
* ``forcelearn calibrate`` (mounting estimated, default orientations, passes
  repeated until the centre of mass's sigma meets its target), then a
  session with the file, which zeroes tool down and visits ``--orientations``
  random orientations (tilt 0..60 deg about a random horizontal axis, then a
  turn of -90..90 deg about the vertical; an orientation the robot refuses is
  drawn again), 200 samples each, all after the one zero of the session's
  start (``--tare``: the cell tares before each turn instead, as a task does,
  and checks there that the tool fits).

It prints one line per tool (with the centre of mass's stated sigma against its
target, the passes and the calibration's cell time) and a summary against the
issue's bounds: mass
within 0.5 % + 5 g, centre of mass within 1 mm + 0.5 % (of its distance from
the sensor), and every compensated free-space force axis, as read, within
what a site can expect at every orientation: 3 sqrt(sigma^2 + d^2 t), sigma
the sensor's noise std, d its bias drift per sqrt(s) (the model's figures, a
data sheet's on site) and t the time since the last zero (or tare), on the
robot controller's clock (the cell's one clock when emulated).
Exit status 1 if any tool misses one. ``--only`` runs the listed tools alone
(the draws of the others are replayed; exact when no orientation was refused).
"""

from __future__ import annotations

import argparse
import io
import math
import sys
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from forcelearn.calibration import dumps, load_calibration
from forcelearn.devices import STANDARD_GRAVITY_M_S2, TOOL_DOWN, Pose
from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams
from forcelearn.emulators.netft.sensor_model import NetFtModelParams
from forcelearn.errors import LinkError, ToolMismatch
from forcelearn.site import CellSession, load_cell_config
from forcelearn.tools.commands.calibrate import calibrate
from forcelearn.tools.commands.calibrate_guard import turned
from forcelearn.tools.experiments.calibration_plan import CalibrationPlan, slerp_steps

PLAN = CalibrationPlan(record_s=1.0, samples_per_pose=400, settle_s=0.2, settle_timeout_s=5.0)
"""The study's plan: the default orientations, shorter recordings than on site."""
MARGIN = 1.25
"""A scaled sensor holds this many times the tool's load at 0.9 of its full scale."""
SAMPLES = 200
"""Samples averaged at each checked orientation."""
CHECK_POSITION = (900.0, 0.0, 450.0)
TARE_MAX_N = 5.0
"""A tare between orientations is refused above this free-space normal force (N)."""


@dataclass(frozen=True)
class Tool:
    """One drawn tool (kg, mm, quaternion w x y z) and the sensor's scale factor."""

    mass_kg: float
    com_mm: tuple[float, float, float]
    contact_mm: tuple[float, float, float]
    mounting: tuple[float, float, float, float]
    scale: float


def draw_tool(rng: np.random.Generator, cell: str) -> Tool:
    """A tool in the issue's ranges, and the factor its sensor model is scaled by."""
    mass = float(math.exp(rng.uniform(math.log(0.1), math.log(15.0))))
    radius, azimuth = rng.uniform(0.0, 200.0), rng.uniform(0.0, 2 * math.pi)
    com = (radius * math.cos(azimuth), radius * math.sin(azimuth), float(rng.uniform(0.0, 250.0)))
    contact = (0.0, 0.0, float(rng.uniform(150.0, 300.0)))
    x, y, z, w = Rotation.random(random_state=rng).as_quat()
    model = NetFtModelParams() if cell == "netft" else Jr3ModelParams()
    fs = np.asarray(model.ranges if isinstance(model, NetFtModelParams) else model.full_scales)
    weight = mass * STANDARD_GRAVITY_M_S2
    moment = weight * float(np.linalg.norm(com)) / 1000.0
    scale = max(1.0, MARGIN * weight / (0.9 * fs[:3].min()),
                MARGIN * moment / (0.9 * fs[3:].min()))
    return Tool(mass, (float(com[0]), float(com[1]), com[2]), contact,
                (float(w), float(x), float(y), float(z)), float(scale))


def config_text(tool: Tool, cell: str) -> str:
    """The cell config of one tool: its [emulator.tool] and, if scaled, its sensor model."""
    document: dict[str, Any] = {"sensor": {"kind": "netft"}} if cell == "netft" else {}
    emulator: dict[str, Any] = {"tool": {
        "mass_kg": tool.mass_kg, "com_mm": list(tool.com_mm),
        "contact_point_mm": list(tool.contact_mm), "mounting_quaternion": list(tool.mounting)}}
    if tool.scale > 1.0:
        model = NetFtModelParams() if cell == "netft" else Jr3ModelParams()
        k = tool.scale
        scales = (model.ranges if isinstance(model, NetFtModelParams) else model.full_scales)
        emulator["sensor"] = {
            "ranges" if cell == "netft" else "full_scales": [round(v * k, 1) for v in scales],
            "noise_std": [v * k for v in model.noise_std],
            "bias_drift_per_sqrt_s": [v * k for v in model.bias_drift_per_sqrt_s]}
    document["emulator"] = emulator
    return dumps(document)


def random_orientation(rng: np.random.Generator) -> tuple[float, float, float, float]:
    """Tool down tilted 0..60 deg about a random horizontal axis, turned -90..90 deg about z."""
    azimuth = rng.uniform(0.0, 2 * math.pi)
    tilted = turned(TOOL_DOWN, (math.cos(azimuth), math.sin(azimuth), 0.0),
                    float(rng.uniform(0.0, 60.0)))
    return turned(tilted, (0.0, 0.0, 1.0), float(rng.uniform(-90.0, 90.0)))


def check_orientations(session: CellSession, rng: np.random.Generator, count: int,
                       zeroed_s: float, tare: bool = False) -> tuple[float, float, int]:
    """Worst compensated free-space force over ``count`` reachable orientations; redraws.

    Returns (worst |F| / sigma, worst |F| / (3 sqrt(sigma^2 + d^2 t)), the
    orientations the arm refused): sigma the noise std, d the bias drift per
    sqrt(s), t the controller's time (s) since ``zeroed_s`` or the last tare. With
    ``tare`` the cell tares before each turn (checking the tool fits there).
    """
    cell, sensor, robot = session.cell, session.sensor, session.robot
    assert cell is not None and cell.compensation is not None and robot is not None
    params = session.sensor_emulator.model.params
    sigma = np.asarray(params.noise_std, dtype=float)[:3]
    drift = np.asarray(params.bias_drift_per_sqrt_s, dtype=float)[:3]
    here = cell.read_pose()
    worst, worst_of_bound, refused, done = 0.0, 0.0, 0, 0
    while done < count:
        target = random_orientation(rng)
        if tare and done:
            try:
                cell.tare(max_reading_n=TARE_MAX_N)
            except ToolMismatch as exc:
                print(f"    {exc}")
                return math.inf, math.inf, refused
            zeroed_s = robot.wait_in_position(5.0, 0.0)
        try:
            for step in slerp_steps(here.quaternion, target, 10.0):
                cell.move_to(Pose(*CHECK_POSITION, step))
                here = Pose(*CHECK_POSITION, step)
        except LinkError:
            refused += 1  # out of the arm's reach: drawn again
            here = cell.read_pose()
            continue
        reached = cell.reached_pose()
        samples = [sensor.read() for _ in range(SAMPLES)]
        mean = np.array([cell.compensation(s.wrench, reached) for s in samples]).mean(axis=0)[:3]
        elapsed = robot.wait_in_position(5.0, 0.0) - zeroed_s
        bound = 3.0 * np.sqrt(sigma**2 + drift**2 * max(elapsed, 0.0))
        worst = max(worst, float(np.max(np.abs(mean) / sigma)))
        worst_of_bound = max(worst_of_bound, float(np.max(np.abs(mean) / bound)))
        done += 1
    return worst, worst_of_bound, refused


def study(cell: str, tools: int, seed: int, orientations: int, folder: Path,
          tare: bool = False, only: set[int] | None = None) -> int:
    """Run the study; returns the number of tools that miss a bound."""
    rng = np.random.default_rng(seed)
    print(f"cell {cell}, {tools} tools, seed {seed}, {orientations} orientations each")
    print(" #   mass kg  err g (lim)    |c| mm  err mm (lim)  sigma mm (target)  passes  "
          "cell s  mount err deg  scale  |F|/sigma  |F|/bound  refused")
    failures = 0
    for i in range(tools):
        tool = draw_tool(rng, cell)
        if only is not None and i not in only:
            for _ in range(orientations):
                random_orientation(rng)
            continue
        config_path = folder / f"{cell}-{i}.toml"
        config_path.write_text(config_text(tool, cell))
        out = folder / f"{cell}-{i}-cal.toml"
        config = load_cell_config(config_path)
        with CellSession(replace(config, calibration_file=None), seed=seed + i) as opened:
            assert opened.robot is not None
            began_s = opened.robot.wait_in_position(5.0, 0.0)
            calibrate(config, PLAN, out_path=out, seed=seed + i, progress=False,
                      stream=io.StringIO(), session=opened)
            cell_s = opened.robot.wait_in_position(5.0, 0.0) - began_s
        cal = load_calibration(out)
        passes = max((int(p.name.rsplit("pass ", 1)[1]) for p in cal.tool.poses
                      if ", pass " in p.name), default=1)
        config_path.write_text(config_text(tool, cell) + f'[calibration]\nfile = "{out.name}"\n')
        with CellSession(load_cell_config(config_path), seed=seed + 1000 + i) as session:
            assert session.cell is not None
            assert session.robot is not None  # the session zeroed on opening:
            zeroed_s = session.robot.wait_in_position(5.0, 0.0)  # the controller's time
            session.cell.move_in_steps(Pose(*CHECK_POSITION, TOOL_DOWN), 10.0)
            worst, of_bound, refused = check_orientations(session, rng, orientations,
                                                          zeroed_s, tare)
        mass_err = abs(cal.tool.mass_kg - tool.mass_kg)
        mass_lim = 0.005 * tool.mass_kg + 0.005
        distance = float(np.linalg.norm(tool.com_mm))
        com_err = float(np.linalg.norm(np.subtract(cal.tool.com_mm, tool.com_mm)))
        com_lim = 1.0 + 0.005 * distance
        mount_err = math.degrees(2 * math.acos(min(1.0, abs(float(
            np.dot(cal.tool.mounting_quaternion, tool.mounting))))))
        ok = mass_err <= mass_lim and com_err <= com_lim and of_bound <= 1.0
        failures += not ok
        sigma = float(np.linalg.norm(cal.tool.com_std_mm))
        print(f"{i:2d}  {tool.mass_kg:7.3f}  {1000 * mass_err:5.1f} ({1000 * mass_lim:4.1f})  "
              f"{distance:7.1f}  {com_err:5.2f} ({com_lim:4.2f})  {sigma:8.2f} "
              f"({com_lim / 3:4.2f})  {passes:6d}  {cell_s:6.0f}  {mount_err:13.3f}  "
              f"{tool.scale:5.2f}  {worst:9.2f}  {of_bound:9.2f}  {refused:7d}"
              f"{'' if ok else '  MISSED'}",
              flush=True)
    ran = tools if only is None else len(only & set(range(tools)))
    print(f"{cell}: {ran - failures}/{ran} tools within every bound")
    return failures


def main(argv: list[str] | None = None) -> int:
    """Command line: the cell(s), the number of tools, the seed."""
    parser = argparse.ArgumentParser(prog="python -m forcelearn.tools.calibration_study",
                                     description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--cell", choices=("jr3", "netft", "both"), default="both")
    parser.add_argument("--tools", type=int, default=20)
    parser.add_argument("--orientations", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--tare", action="store_true",
                        help="tare before each turn (and check the tool fits there)")
    parser.add_argument("--only", type=int, nargs="+", metavar="I",
                        help="run only these tools (0-based), replaying the others' draws")
    args = parser.parse_args(argv)
    only = set(args.only) if args.only else None
    failures = 0
    with tempfile.TemporaryDirectory() as folder:
        for cell in (("jr3", "netft") if args.cell == "both" else (args.cell,)):
            failures += study(cell, args.tools, args.seed, args.orientations, Path(folder),
                              args.tare, only)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
