"""Run the paper's §5 surface job from Python: the library's door to ``forcelearn run``.

::

    from forcelearn.runs import run_surface

    summary = run_surface("runs/first", trials=40, seed=0)  # the built-in emulated cell
    print(summary["converged_trial"], summary["final_force_rms_n"])
    summary = run_surface("runs/first", trials=80, resume=True)  # 40 trials more

:func:`run_surface` writes the same run directory as ``forcelearn run``
(docs/run-directory.md: checkpoint, summary.json, trials.csv, step logs,
records, figures) with the same engine
(:mod:`forcelearn.tools.experiments.surface_run`), so a run started here
resumes there and the other way round. It returns the summary (summary.json's
content). Progress, warnings and each step reach the caller through the hooks.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from forcelearn.learning import SRVLearner
from forcelearn.tools.experiments.surface_run import execute
from forcelearn.tools.experiments.surface_state import prepare_run
from forcelearn.trainer import StepHook, TrialRecord

__all__ = ["run_surface"]


def run_surface(
    out: str | Path,
    config: str | Path | None = None,
    *,
    trials: int | None = None,
    seed: int | None = None,
    resume: bool = False,
    on_trial: Callable[[TrialRecord, SRVLearner], Any] | None = None,
    on_warning: Callable[[str], Any] | None = None,
    on_step: StepHook | None = None,
) -> dict[str, Any]:
    """Run (or resume) the surface job in the run directory ``out``; return its summary.

    Args:
        out: the run directory (created; must not hold a run unless ``resume``).
        config: a cell config TOML (docs/config.md); None: the built-in emulated
            cell. A resumed run reads the copy in ``out`` and takes no config.
        trials: the run's total trials (a resume continues up to it); None: the
            config's ``[run] trials``, or on resume the count the run started with.
        seed: the random seed; None: the config's ``[run] seed``. A resume keeps
            the run's own.
        resume: continue the run whose checkpoint is in ``out``.
        on_trial: called after each trial's checkpoint with its record and the learner.
        on_warning: called with each warning's text (stuck learning, out of reach).
        on_step: called with each step's log row as it is made.

    Raises:
        ValueError: ``trials`` below 1, or ``config``/``seed`` given with ``resume``.
        StateFileError: nothing to resume in ``out``, a run already there (new run),
            or a damaged checkpoint.
        ConfigError: the config is invalid.
        ForcelearnError: a device failed; the robot was stopped and the outputs
            hold every whole trial (resume to continue).
    """
    if trials is not None and trials < 1:
        raise ValueError(f"trials must be >= 1, not {trials}")
    if resume and (config is not None or seed is not None):
        raise ValueError(
            "a resumed run keeps its own config and seed: give only out (and optionally trials)"
        )
    run, checkpoint = prepare_run(
        Path(config) if config is not None else None, Path(out), trials, seed, resume
    )
    return execute(run, checkpoint, on_trial=on_trial, on_warning=on_warning, on_step=on_step)
