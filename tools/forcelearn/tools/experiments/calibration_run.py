"""The measuring steps of ``forcelearn calibrate``, on an open cell (emulated or real alike).

1. **Free space.** Automatic: move the tool point to the plan's position in
   straight steps under ``safety.max_step_mm`` (one sample read after each,
   so the force limit can stop the robot), then turn to the first
   orientation. Manual: the operator jogs there and presses Enter.
2. **Bias and noise.** Zero the offsets through the protocol, record for
   ``record_s``, estimate the residual bias, the 6x6 covariance, the drift and
   the sample rate achieved (with a progress bar).
3. **Tool load.** For each orientation: turn to it about the fixed tool point
   in steps of at most ``max_rotation_step_deg`` (or ask the operator to jog
   there), wait until the robot reports in position, dwell ``settle_s``, read
   blocks until two consecutive block means agree within 4 standard errors on
   every axis, average ``samples_per_pose`` samples, and read back the
   orientation actually reached. Then fit (:func:`~forcelearn.calibration.fit_tool_load`).

Any device error (sensor silent, robot refusing a pose, a safety limit) stops
the robot and ends in :class:`~forcelearn.errors.CalibrationError` naming the
step; nothing here writes a file.
"""

from __future__ import annotations

import contextlib
import logging
import math
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TextIO

import numpy as np
from tqdm import tqdm

from forcelearn.calibration import (
    AXES,
    NoiseEstimate,
    ToolLoad,
    check_pose_set,
    estimate_noise,
    fit_tool_load,
)
from forcelearn.devices import Pose
from forcelearn.errors import CalibrationError, ForcelearnError, NotInPosition
from forcelearn.site.session import CellSession
from forcelearn.tools.experiments.calibration_plan import CalibrationPlan, NamedPose, slerp_steps

log = logging.getLogger(__name__)

READ_CHUNK = 50
"""Samples per read_many call while recording (and per settling block)."""
SETTLE_SIGMAS = 4.0
"""Two block means closer than this many standard errors, on every axis, count as settled."""

Ask = Callable[[str], str]


@dataclass(frozen=True)
class Measurement:
    """What the steps measured: noise (step 2) and the tool-load fit (step 3)."""

    noise: NoiseEstimate
    tool: ToolLoad


class Calibrator:
    """Runs the steps on an open :class:`CellSession`.

    Args:
        session: the open cell (opened without a calibration file).
        plan: position, orientations and times.
        manual: ask the operator to jog to each pose instead of moving the robot.
        ask: how to ask the operator (``input``); gets the prompt, returns the answer.
        progress: show a progress bar while recording.
        out: where to print per-pose lines.
    """

    def __init__(self, session: CellSession, plan: CalibrationPlan, *, manual: bool = False,
                 ask: Ask = input, progress: bool = True, out: TextIO | None = None) -> None:
        if session.robot is None or session.sensor is None or session.cell is None:
            raise ValueError("the cell session is not open")
        self.robot, self.sensor, self.cell = session.robot, session.sensor, session.cell
        self.max_step_mm = session.config.safety.max_step_mm
        self.sample_period_s = session.config.filter.sample_period_s
        self.plan, self.manual, self.ask = plan, manual, ask
        self.progress, self.out = progress, out or sys.stdout
        self._orientation = plan.poses[0].quaternion if plan.poses else (1.0, 0.0, 0.0, 0.0)
        self.in_position_s = math.nan
        """The controller's time (s) at the end of the last wait in position."""

    # ---- the steps --------------------------------------------------------------------
    def run(self) -> Measurement:
        """Measure bias, noise and tool load; raises CalibrationError on any failure."""
        plan = self.plan
        if not self.manual:  # refuse a bad set before the robot moves at all
            check_pose_set([p.quaternion for p in plan.poses], plan.max_condition)
        with self._step("moving to the free-space position"):
            self._go_to_start()
        with self._step("bias and noise"):
            noise = self._bias_and_noise()
        names, quaternions, means, counts = [], [], [], []
        for number, pose in enumerate(plan.poses, start=1):
            with self._step(f"pose {number}/{len(plan.poses)} ({pose.name})"):
                measured = self._measure_pose(number, pose, noise.std)
            if measured is None:
                continue
            names.append(pose.name)
            quaternions.append(measured[0])
            means.append(measured[1])
            counts.append(measured[2])
        if not self.manual:
            with self._step("turning back to the first orientation"):
                self._turn_to(plan.poses[0].quaternion)
        tool = fit_tool_load(quaternions, np.array(means).reshape(-1, 6),
                             axis_std=np.maximum(noise.std, 1e-6), names=names,
                             samples=counts, limit=plan.max_condition)
        return Measurement(noise, tool)

    @contextlib.contextmanager
    def _step(self, what: str) -> Iterator[None]:
        """Turn a device error into CalibrationError naming the step; stop the robot."""
        try:
            yield
        except CalibrationError as exc:
            self.cell.stop()
            raise CalibrationError(f"{what}: {exc}") from exc
        except ForcelearnError as exc:
            self.cell.stop()
            raise CalibrationError(
                f"{what}: {type(exc).__name__}: {exc}; the robot was stopped"
            ) from exc

    def _go_to_start(self) -> None:
        if self.manual:
            self._prompt("Jog the tool into free space (nothing touching it, cables clear) "
                         "and press Enter to zero the sensor and record its noise: ")
            self._orientation = self.robot.read_pose().quaternion
            return
        here = self.cell.read_pose()
        self._orientation = here.quaternion
        target = Pose(*self.plan.position_mm, here.quaternion)
        log.info("moving to %s mm in steps of at most %s mm", self.plan.position_mm,
                 self.max_step_mm)
        self.cell.move_in_steps(target, self.max_step_mm, guard_force=True)
        self._turn_to(self.plan.poses[0].quaternion)

    def _bias_and_noise(self) -> NoiseEstimate:
        self._wait_settled_robot()
        zero_quaternion = self.robot.read_pose().quaternion
        self.sensor.zero_offsets()
        # record_s of the sensor's own time: as many samples as that holds at the configured
        # sample period (the host's clock would make an emulated recording depend on its load)
        count = max(READ_CHUNK, math.ceil(self.plan.record_s / self.sample_period_s))
        wrenches: list[np.ndarray] = []
        stamps: list[float] = []
        bar = tqdm(total=count, unit="sample", disable=not self.progress, file=sys.stderr,
                   desc="bias and noise")
        with bar:
            start = time.monotonic()
            while len(wrenches) < count:
                for sample in self.sensor.read_many(min(READ_CHUNK, count - len(wrenches))):
                    wrenches.append(sample.wrench)
                    stamps.append(sample.timestamp_s)
                    bar.update(1)
                rate = len(wrenches) / max(time.monotonic() - start, 1e-9)
                bar.set_postfix_str(f"{rate:.0f}/s", refresh=False)
        noise = estimate_noise(np.array(wrenches), np.array(stamps), zero_quaternion)
        print(f"bias and noise: {noise.samples} samples in {noise.duration_s:.2f} s "
              f"({noise.rate_hz:.0f} samples/s)", file=self.out)
        return noise

    def _measure_pose(self, number: int, pose: NamedPose, std: np.ndarray
                      ) -> tuple[tuple[float, float, float, float], np.ndarray, int] | None:
        """Return (orientation reached, mean wrench, samples), or None if the operator skips."""
        if self.manual:
            q = ", ".join(f"{c:.4f}" for c in pose.quaternion)
            answer = self._prompt(
                f"Jog to pose {number}/{len(self.plan.poses)}: {pose.name} (quaternion [{q}]), "
                "tool in free space; Enter = measure, s = skip: ")
            if answer.strip().lower().startswith("s"):
                return None
        else:
            self._turn_to(pose.quaternion)
        self._wait_settled_robot()
        self._settle_reading(std)
        samples = self.sensor.read_many(self.plan.samples_per_pose)
        saturated = [AXES[i] for i in range(6) if any(s.saturated[i] for s in samples)]
        if saturated:
            raise CalibrationError(
                f"the sensor is near saturation on {saturated}: the tool is touching "
                "something or is too heavy for the sensor's full scale"
            )
        reached = self.robot.read_pose().quaternion
        mean = np.mean([s.wrench for s in samples], axis=0)
        print(f"pose {number}: {pose.name}: {len(samples)} samples, mean "
              f"{np.array2string(mean, precision=3, suppress_small=True)}", file=self.out)
        return reached, mean, len(samples)

    # ---- motion and settling ----------------------------------------------------------
    def _turn_to(self, quaternion: tuple[float, float, float, float]) -> None:
        """Turn about the fixed tool point in small steps, reading one sample after each."""
        steps = slerp_steps(self._orientation, quaternion, self.plan.max_rotation_step_deg)
        for i, q in enumerate(steps, start=1):
            self.cell.move_to(Pose(*self.plan.position_mm, q))
            self._orientation = q
            if i < len(steps):
                self.cell.measure_force_n(1)  # the force limit watches the turn

    def _wait_settled_robot(self) -> None:
        """Wait until the robot reports in position, then dwell ``settle_s`` (robot's clock).

        Keeps the controller's time at the end of the wait in ``in_position_s`` (s).
        """
        try:
            self.in_position_s = self.robot.wait_in_position(self.plan.settle_timeout_s,
                                                             self.plan.settle_s)
        except NotInPosition as exc:
            raise CalibrationError(
                f"the robot was not in position within {self.plan.settle_timeout_s} s "
                f"(plan settle_timeout_s): {exc}"
            ) from exc

    def _settle_reading(self, std: np.ndarray) -> None:
        """Read blocks until two consecutive means agree within SETTLE_SIGMAS standard errors."""
        tolerance = SETTLE_SIGMAS * np.maximum(std, 1e-6) * math.sqrt(2.0 / READ_CHUNK)
        # settle_timeout_s of the sensor's own time, as blocks of samples (the host's clock
        # would make an emulated calibration depend on the host's load)
        blocks = max(2, math.ceil(self.plan.settle_timeout_s / self.sample_period_s / READ_CHUNK))
        previous = np.mean([s.wrench for s in self.sensor.read_many(READ_CHUNK)], axis=0)
        for block in range(1, blocks + 1):
            current = np.mean([s.wrench for s in self.sensor.read_many(READ_CHUNK)], axis=0)
            if np.all(np.abs(current - previous) <= tolerance):
                return
            if block == blocks:
                worst = AXES[int(np.argmax(np.abs(current - previous) / tolerance))]
                raise CalibrationError(
                    f"the reading did not settle within {self.plan.settle_timeout_s} s "
                    f"(worst axis {worst}): the tool may be touching something, swinging "
                    "or its cable pulling; check and run again"
                )
            previous = current

    def _prompt(self, text: str) -> str:
        try:
            return self.ask(text)
        except EOFError as exc:
            raise CalibrationError("no answer from the operator (end of input)") from exc
