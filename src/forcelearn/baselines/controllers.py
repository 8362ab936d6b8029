"""The methods of the comparison, each a :class:`~forcelearn.baselines.runner.Controller`.

=================  =========================================================================
``srv``            the paper's SRV learner over BOXES, driven through the env (same result
                   as the native trainer for a seed)
``pi``             explicit force control: a PI loop on the filtered force error that
                   corrects Y every step; gains scaled by the stiffness measured at the
                   trial's first step; nothing carried from trial to trial
``ilc``            iterative learning control: a P-type update of the 20-step Y path from
                   trial to trial, learning gain L, zero-phase Q-filter
``cma``            black-box path search: CMA-ES over the 20 Y offsets, one trial per
                   evaluation
=================  =========================================================================

Every method starts from what the env's surface probe found, as ``forcelearn
run`` does (:class:`CellPrior`, from ``reset``'s info): offsets are relative to
the output map's centre, the Y where the probe expects the desired force, and
bounded by its half-range. ``pi``, ``ilc`` and ``cma`` start from the probe's
surface model, the path where its fits give the desired force at each step
(``probe_path_mm``: the feedforward of ``pi``, the first path of ``ilc``, the
initial mean of ``cma``); ``srv`` starts at μ = 0 (the map's centre, through
its output map), as the paper's learner starts from nothing, or with
``start = "probe"`` on the probe's path (``[run] learner_start``). ``pi`` and
``ilc`` take the probe's stiffness k̂. Without a probe (``[probe] enabled =
false``, or a configured map) they fall back to what an operator would try
first: a constant offset ``probe_offset_mm`` (−4 mm) below the centre, with
k̂ = (F1 − F0) / |probe| measured at that first step (F0 the force at the
start pose, F1 after the first step).

The surface task only: Y offsets in mm, forces in N. Env actions are offsets
divided by the map's half-range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from forcelearn.learning import Action, SRVLearner, SRVParams
from forcelearn.tasks.evaluation import FAILURE_R
from forcelearn.tasks.surface_warm_start import check_learner_start, warm_start
from forcelearn.trainer import TrialRecord

MIN_STIFFNESS_N_PER_MM = 0.2
"""Smallest stiffness estimate accepted (a probe that met almost no force), N/mm."""
MAX_STIFFNESS_N_PER_MM = 50.0
"""Largest stiffness estimate accepted, N/mm."""


def measured_stiffness(start_force_n: float, probe_force_n: float, probe_offset_mm: float) -> float:
    """k̂ = (F1 − F0) / |probe| in N/mm, clipped to a sane range."""
    k = (probe_force_n - start_force_n) / abs(probe_offset_mm)
    return float(np.clip(k, MIN_STIFFNESS_N_PER_MM, MAX_STIFFNESS_N_PER_MM))


@dataclass(frozen=True)
class CellPrior:
    """What a method knows of the cell before learning: the env's probe and output map."""

    max_offset_mm: float
    """Half-range of the Y offsets around the map's centre, mm."""
    stiffness_n_per_mm: float
    """The probe's stiffness, N/mm; NaN without a probe (measure it at the first step)."""
    path_mm: tuple[float, ...] | None = None
    """The probe's surface model: per step, the offset where it expects the desired force."""

    @classmethod
    def from_info(cls, info: dict[str, Any], fallback_offset_mm: float) -> CellPrior:
        """From reset's info: output_map, probe_stiffness_n_per_mm, probe_path_mm."""
        choice = info.get("output_map") or {}
        k = info.get("probe_stiffness_n_per_mm")
        path = info.get("probe_path_mm")
        return cls(
            float(choice.get("max_offset_mm", fallback_offset_mm)),
            math.nan if k is None else float(k),
            None if path is None else tuple(float(v) for v in path),
        )

    @property
    def probed(self) -> bool:
        """True when the probe measured the stiffness."""
        return math.isfinite(self.stiffness_n_per_mm)

    def first_path_mm(self, steps: int, probe_offset_mm: float) -> np.ndarray:
        """The first guess per step: the probe's path (within the range), else a constant.

        Without a probe path: the centre after a probe, else ``probe_offset_mm`` below it.
        """
        if self.path_mm is not None and len(self.path_mm) == steps:
            limit = self.max_offset_mm
            path: np.ndarray = np.clip(np.asarray(self.path_mm, dtype=float), -limit, limit)
            return path
        return np.full(steps, 0.0 if self.probed else probe_offset_mm)


class SRVController:
    """The paper's learner acting through an env (its output map gives env actions).

    Args:
        env: the unwrapped forcelearn env (``grid``, ``learner_input``, ``learner_action``).
        params: SRV hyperparameters.
        seed: the learner's random seed.
    """

    name = "srv"

    def __init__(self, env: Any, params: SRVParams, seed: int, start: str = "cold"):
        n_outputs = int(env.action_space.shape[0])
        self.env = env
        self.learner = SRVLearner(env.grid, n_outputs, params, rng=seed, output=env.learner_action)
        self._action: Action | None = None
        self.switch_trial: int | None = None
        self.start = check_learner_start(start)
        """"cold" (μ = 0) or "probe" (the warm start of ``[run] learner_start``)."""
        self._started = False

    def begin(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Before the first trial, with ``start = "probe"``: the probe's warm start."""
        if self._started:
            return
        self._started = True
        probe = getattr(self.env, "probe", None)
        if self.start == "probe" and probe is not None and probe.fits:
            spec = self.env.task_spec
            warm_start(
                self.learner, probe, spec, self.env.output_map.output(abs(spec.z_step_mm))
            )

    def act(self, obs: np.ndarray) -> np.ndarray:
        """S3-S4: draw a ~ N(μ, σ) in the input box; the output map makes it an env action."""
        action = self.learner.act(self.env.learner_input(obs))
        self._action = action
        return action.output

    def observe(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """S7-S8 with r = −reward."""
        if self._action is None:
            raise RuntimeError("observe() before act(): no action to learn from")
        self.learner.learn(self._action, float(info["r"]))

    def end(self, record: TrialRecord) -> None:
        """S9: the global criterion."""
        if self.learner.end_trial(success=not record.failed):
            self.switch_trial = record.index


@dataclass(frozen=True)
class ForceControlParams:
    """PI force control (admittance-style: force error → Y correction), per step."""

    kp: float = 0.1
    """Proportional gain, as a fraction of the inverse stiffness."""
    ki: float = 1.0
    """Integral gain per step, as a fraction of the inverse stiffness (1: deadbeat on a
    static sponge). Kp, Ki picked from a small grid on seed 0 of the default cell
    (docs/results/baselines.md): larger gains oscillate (the relaxing sponge is stiffer
    than k̂ just after a move), smaller ones lag further behind the surface."""
    probe_offset_mm: float = -4.0
    """Without a probe: Y offset of the first step of the first trial; k̂ is measured there."""


class ForceController:
    """Explicit force control: Y_{k+1} = Y_ff,k+1 + (Kp e_k + Ki Σ_{i≤k} e_i) / k̂, no memory.

    e_k is the filtered force error (the cell's Kalman filter) after step k
    (positive: pressing too hard, so Y rises: the sponge pushes along +Y);
    Y_ff is the feedforward: the probe's surface model (:class:`CellPrior`),
    else a constant. Every trial's first step goes to Y_ff,1; the loop
    corrects from the first measured error on. k̂ is the probe's stiffness; without a probe
    it is measured once, at the first step of the first trial, which goes to
    ``probe_offset_mm`` (like an operator's stiffness test). Nothing is carried
    from trial to trial.
    """

    name = "pi"

    def __init__(self, env: Any, params: ForceControlParams | None = None):
        self.params = params or ForceControlParams()
        self.spec = env.task_spec
        self.prior: CellPrior | None = None
        self.stiffness_n_per_mm = math.nan
        self._start_force_n = math.nan
        self._integral = 0.0
        self._feedforward = np.zeros(self.spec.steps_per_trial)
        self._step = 0
        self._offset_mm = 0.0

    def begin(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Reset the integrator; the first step goes to the feedforward's first."""
        if self.prior is None:
            self.prior = CellPrior.from_info(info, self.spec.fallback_offset_mm)
            self.stiffness_n_per_mm = self.prior.stiffness_n_per_mm
            self._feedforward = self.prior.first_path_mm(
                self.spec.steps_per_trial, self.params.probe_offset_mm
            )
        self._start_force_n = float(info["start_force_n"])
        self._step = 0
        self._integral = 0.0
        self._offset_mm = float(self._feedforward[0])

    def act(self, obs: np.ndarray) -> np.ndarray:
        """The env action for the present Y offset."""
        return np.array([_action_of(self._offset_mm, self._limit())])

    def observe(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Measure k̂ after the very first step if no probe did, then the PI correction."""
        if not math.isfinite(self.stiffness_n_per_mm):
            self.stiffness_n_per_mm = measured_stiffness(
                self._start_force_n, float(info["force_n"]), self.params.probe_offset_mm
            )
        self._step += 1
        self._correct(float(info["force_error_n"]))

    def end(self, record: TrialRecord) -> None:
        """Nothing is carried to the next trial (k̂ is a constant of the cell)."""

    def _limit(self) -> float:
        if self.prior is None:
            raise RuntimeError("act() before begin(): the map is not known yet")
        return self.prior.max_offset_mm

    def _correct(self, error_n: float) -> None:
        p = self.params
        self._integral += error_n
        correction = (p.kp * error_n + p.ki * self._integral) / self.stiffness_n_per_mm
        feedforward = self._feedforward[min(self._step, len(self._feedforward) - 1)]
        limit = self._limit()
        self._offset_mm = float(np.clip(feedforward + correction, -limit, limit))


@dataclass(frozen=True)
class ILCParams:
    """P-type ILC of the Y path: p_{j+1} = Q(p_j + L e_j / k̂) (too much force raises Y)."""

    learning_gain: float = 0.5
    """L: fraction of the stiffness-scaled error corrected per trial (0 < L < 2 on a static map)."""
    q_weights: tuple[float, float, float] = (0.25, 0.5, 0.25)
    """Zero-phase Q-filter along the path (edges repeat the end values); (0, 1, 0) is none."""
    probe_offset_mm: float = -4.0
    """Without a probe: the first trial's constant path; k̂ is measured at its first step."""


def q_filter(path: np.ndarray, weights: tuple[float, float, float]) -> np.ndarray:
    """Zero-phase 3-tap filter along the path, edges padded with the end values."""
    padded = np.concatenate([path[:1], path, path[-1:]])
    w0, w1, w2 = weights
    return w0 * padded[:-2] + w1 * padded[1:-1] + w2 * padded[2:]


class ILCController:
    """Iterative learning control of the 20 Y offsets (feedforward only, no in-trial feedback).

    A trial that failed at step m has no errors past m: they are taken as the
    error at m (the path is corrected in the same direction from there on).
    """

    name = "ilc"

    def __init__(self, env: Any, params: ILCParams | None = None):
        self.params = params or ILCParams()
        self.spec = env.task_spec
        self.prior: CellPrior | None = None
        self.path_mm = np.zeros(self.spec.steps_per_trial)
        self._stiffness = math.nan
        self._start_force_n = math.nan
        self._errors: list[float] = []

    def begin(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """A new pass along the present path (the first: the first guess, constant)."""
        if self.prior is None:
            self.prior = CellPrior.from_info(info, self.spec.fallback_offset_mm)
            self._stiffness = self.prior.stiffness_n_per_mm
            self.path_mm = self.prior.first_path_mm(
                self.spec.steps_per_trial, self.params.probe_offset_mm
            )
        self._start_force_n = float(info["start_force_n"])
        self._errors = []

    def act(self, obs: np.ndarray) -> np.ndarray:
        """The path's offset of this step as an env action."""
        return np.array([_action_of(self.path_mm[len(self._errors)], self._limit())])

    def _limit(self) -> float:
        if self.prior is None:
            raise RuntimeError("act() before begin(): the map is not known yet")
        return self.prior.max_offset_mm

    def observe(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Keep the error; the first trial's first step measures k̂."""
        if not math.isfinite(self._stiffness):
            self._stiffness = measured_stiffness(
                self._start_force_n, float(info["force_n"]), self.path_mm[0]
            )
        self._errors.append(float(info["force_error_n"]))

    def end(self, record: TrialRecord) -> None:
        """The ILC update of the whole path."""
        errors = np.full(self.path_mm.shape, self._errors[-1])
        errors[: len(self._errors)] = self._errors
        updated = self.path_mm + self.params.learning_gain * errors / self._stiffness
        limit = self._limit()
        self.path_mm = np.clip(q_filter(updated, self.params.q_weights), -limit, limit)


NO_PROBE_SIGMA0_MM = 2.0
"""CMA-ES's initial step size without a probe's stiffness to scale it, mm."""


@dataclass(frozen=True)
class PathSearchParams:
    """CMA-ES over the Y path (offsets in mm)."""

    sigma0_tolerance_share: float = 0.4
    """Initial step size as a share of the failure tolerance over the probe's stiffness:
    σ0 = share · tolerance / k̂ (mm), so a 1σ step moves the force by this share of the
    band on any sponge (0.4: about 2 mm on the default cell, 9.8 N over 2.05 N/mm)."""
    sigma0_mm: float | None = None
    """A fixed initial step size (mm) instead; also used without a probe (None: 2.0 mm)."""
    popsize: int = 0
    """Candidates per generation; 0: CMA-ES's default 4 + ⌊3 ln 20⌋ = 12."""
    probe_offset_mm: float = -4.0
    """Without a probe: the initial mean's constant offset (the same first guess as pi, ilc)."""


class PathSearchController:
    """Black-box search of the 20 Y offsets with CMA-ES; one trial evaluates one candidate.

    The objective is the force RMS over the 20 steps, a step not reached (the
    trial failed before it) counting as an error of ``tolerance_n`` (10 N).
    """

    name = "cma"

    def __init__(self, env: Any, seed: int, params: PathSearchParams | None = None):
        self.params = params or PathSearchParams()
        self.spec = env.task_spec
        self.seed = seed
        self.prior: CellPrior | None = None
        self.es: Any = None
        self._pending: list[np.ndarray] = []
        self._told: list[float] = []
        self._asked: list[np.ndarray] = []
        self.path_mm = np.zeros(self.spec.steps_per_trial)
        self._errors: list[float] = []
        self.sigma0_mm = math.nan
        """The initial step size in use (mm), once the search has started."""

    def _start_search(self, prior: CellPrior) -> Any:
        import cma

        limit = prior.max_offset_mm
        options: dict[str, Any] = {
            "seed": self.seed + 1,  # cma treats 0 as "seed from the clock"
            "bounds": [-limit, limit],
            "verbose": -9,
        }
        if self.params.popsize:
            options["popsize"] = self.params.popsize
        mean = prior.first_path_mm(self.spec.steps_per_trial, self.params.probe_offset_mm)
        self.sigma0_mm = self._sigma0_mm(prior)
        return cma.CMAEvolutionStrategy(mean, self.sigma0_mm, options)

    def _sigma0_mm(self, prior: CellPrior) -> float:
        """The initial step size (mm): fixed, else scaled to the band and the probe's k̂."""
        params = self.params
        if params.sigma0_mm is not None:
            return params.sigma0_mm
        if not prior.probed:
            return NO_PROBE_SIGMA0_MM
        band_n = self.spec.evaluation.error_n(params.sigma0_tolerance_share)
        sigma = band_n / prior.stiffness_n_per_mm
        return float(min(sigma, prior.max_offset_mm))

    def begin(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Take the next candidate (ask a new generation when none is left)."""
        if self.prior is None:
            self.prior = CellPrior.from_info(info, self.spec.fallback_offset_mm)
            self.es = self._start_search(self.prior)
        if not self._pending:
            self._asked = [np.asarray(c, dtype=float) for c in self.es.ask()]
            self._pending = list(self._asked)
            self._told = []
        self.path_mm = self._pending.pop(0)
        self._errors = []

    def act(self, obs: np.ndarray) -> np.ndarray:
        """The candidate's offset of this step as an env action."""
        if self.prior is None:
            raise RuntimeError("act() before begin(): the map is not known yet")
        return np.array([_action_of(self.path_mm[len(self._errors)], self.prior.max_offset_mm)])

    def observe(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """Keep the error."""
        self._errors.append(float(info["force_error_n"]))

    def end(self, record: TrialRecord) -> None:
        """Score the candidate; tell CMA-ES when the generation is complete."""
        missing_n = self.spec.evaluation.error_n(FAILURE_R)  # a step not reached: a failure
        errors = np.full(self.spec.steps_per_trial, missing_n)
        errors[: len(self._errors)] = self._errors
        self._told.append(float(np.sqrt(np.mean(np.square(errors)))))
        if len(self._told) == len(self._asked):
            self.es.tell(self._asked, self._told)


def _action_of(offset_mm: float, max_offset_mm: float) -> float:
    """Env action of a Y offset (mm), clipped to [-1, 1]."""
    return float(np.clip(offset_mm / max_offset_mm, -1.0, 1.0))
