"""What ``forcelearn twin`` writes: twin.toml (the emulated cell), twin.json, twin.md, figures.

Every parameter is listed with its 1-sigma uncertainty and whether the records
determine it (:meth:`~forcelearn.tools.twin.params.Parameter.determined`, with
the larger of the Jacobian's and the resampled sigma). One that they do not
determine is held at the base config's value or keeps the records' best fit, by
the rule of :func:`~forcelearn.tools.twin.fit.fit_member` (never a value at a bound
of its range), and the report says which, with the trials that would determine it: the uncertainty
extrapolated as ``1/sqrt(n)``, and for wear at least the wear's time constant
in passes.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from forcelearn.site.config import EmulatorConfig
from forcelearn.site.kinds import robot_kind, sensor_kind
from forcelearn.tools.twin.bias import DETECT_SIGMAS, drift_detected
from forcelearn.tools.twin.fit import HOLD_OUT, SCALE_OF, TwinFit
from forcelearn.tools.twin.identify import IDENTIFY_TRIAL
from forcelearn.tools.twin.params import ARM, BY_NAME, SENSOR, Parameter
from forcelearn.tools.twin.source import RunSource


def _row(param: Parameter, value: float, sigma: float, trials: int,
         passes: float, held: bool = False) -> dict[str, Any]:
    determined = param.determined(value, sigma) and not held
    row: dict[str, Any] = {
        "name": param.name, "table": param.table, "unit": param.unit, "value": value,
        "sigma": sigma if math.isfinite(sigma) else None, "determined": determined,
        "determined_below": param.bound(value), "doc": param.doc,
    }
    if not determined:
        bound = param.bound(value)
        if math.isfinite(sigma) and bound > 0:
            row["trials_to_determine"] = math.ceil(trials * (sigma / bound) ** 2)
        else:
            row["trials_to_determine"] = None
            row["note"] = "the records do not constrain it at all"
        if param.wear:
            row["note"] = (f"wear: the records span {passes:.0f} passes; a wear curve is "
                           "determined only over passes comparable to its time constant")
    return row


def undetermined_why(param: Parameter, value: float, jacobian: float, member: float) -> str:
    """Why a fitted parameter the verdict leaves undetermined is so ("" when no one reason).

    ``jacobian``: its Jacobian's 1-sigma; ``member``: the model-selection spread
    (``fit.member_spread``; 0 when none). The spread is named first: it alone leaves it
    undetermined when a member the records do not rule out puts it elsewhere or holds it.
    """
    if not param.determined(value, member):
        return ("a richer member the records do not rule out (it predicts the held-out trials "
                "as well, or fits the fitted trials better) puts it elsewhere or leaves it "
                "loose: the records do not say which member's value is right")
    if param.determined(value, jacobian):
        return ("the Jacobian's sigma is within the bound, but refits without a block of "
                "trials or on the low and high forces apart move it by more: the records do "
                "not pin it (the model may miss something)")
    return ""


def parameter_rows(fit: TwinFit) -> list[dict[str, Any]]:
    """Every parameter of the twin, fitted or held, with its verdict."""
    trials = fit.train_trials
    passes = float(np.nanmax(np.where(fit.train.valid, fit.train.passes, np.nan)))
    rows = []
    for name in fit.chosen.sigmas:
        held = name in fit.chosen.held
        row = _row(BY_NAME[name], fit.chosen.values[name], fit.chosen.sigmas[name], trials,
                   passes, held)
        if held:
            row["note"] = ("held at the base config's value; the uncertainty is the fit's "
                           "when it was free" + ("; " + row["note"] if "note" in row else ""))
        elif name in fit.chosen.jackknife_sigmas:
            jacobian = fit.chosen.jacobian_sigmas[name]
            resampled = fit.chosen.jackknife_sigmas[name]
            row["sigma_jacobian"] = jacobian if math.isfinite(jacobian) else None
            row["sigma_resampled"] = resampled if math.isfinite(resampled) else None
            if name in fit.chosen.held_sigmas:
                row["sigma_held"] = fit.chosen.held_sigmas[name]
            if name in fit.chosen.arm_sigmas:
                row["sigma_arm"] = fit.chosen.arm_sigmas[name]
            if name in fit.chosen.phase_sigmas:
                row["sigma_phase"] = fit.chosen.phase_sigmas[name]
            if name in fit.chosen.experiment_sigmas:
                row["sigma_experiments"] = fit.chosen.experiment_sigmas[name]
            member = fit.chosen.member_sigmas.get(name, 0.0)
            if name in fit.chosen.member_sigmas:
                row["sigma_member"] = member if math.isfinite(member) else None
            why = undetermined_why(BY_NAME[name], row["value"], jacobian, member)
            if not row["determined"] and why:
                row["note"] = why + ("; " + row["note"] if "note" in row else "")
        rows.append(row)
    for param in ARM:
        value = fit.arm.values[param.name]
        if param.name == "start_delay_s":
            value = fit.arm_emulator_delay_s
        row = _row(param, value, fit.arm.sigmas[param.name], trials, passes)
        if not row["determined"]:
            row["note"] = fit.arm.note or (
                "not determined by the moves' timing: the base config's value is kept")
            free = fit.arm.free_sigmas.get(param.name, math.inf)
            if math.isfinite(free):
                row["note"] += f"; fitted free, its 1-sigma was {_fmt(free)} {param.unit}"
        elif param.name == "start_delay_s":
            row["note"] = ("command to motion, including the link's time to send the command: "
                           "twin.toml keeps the base delay (its emulated link adds its own)")
        rows.append(row)
    sensor = fit.sensor
    rows.append(_row(SENSOR[0], sensor.noise_n, sensor.noise_sigma_n, trials, passes))
    drift = _row(SENSOR[1], sensor.drift_n_per_sqrt_s, sensor.drift_sigma, trials, passes)
    if not drift_detected(sensor.drift_n_per_sqrt_s, sensor.drift_sigma):
        drift["determined"] = False
        walked = ""
        if (fit.train.trial == IDENTIFY_TRIAL).any() and sensor.drift_allowed > 0:
            walked = (f" (the identification's zero walks at the {sensor.drift_allowed:.4g} "
                      "N/sqrt(s) the tares allow at 1 sigma: minutes at one place)")
        drift["note"] = (f"{sensor.tares} tares recorded; not told from no drift (under "
                         f"{DETECT_SIGMAS:g} sigma): the fit's bias walk is off{walked} and "
                         "twin.toml keeps the base config's value (task.tare_each_trial = true "
                         "or more trials measure it)")
    elif sensor.drift_source == "free-space reads":
        drift["note"] = (f"{sensor.tares} tares recorded: measured from the free-space reads "
                         "of successive trials (task.tare_each_trial = true measures it "
                         "better)")
    elif sensor.drift_source != "tares" or not math.isfinite(sensor.drift_n_per_sqrt_s):
        drift["note"] = (f"{sensor.tares} tares recorded and no free-space reads: the drift "
                         "needs tares (task.tare_each_trial = true); the base config's value "
                         "is kept")
    rows.append(drift)
    rows = amplitudes_need_their_scales(rows)
    if not fit.represented:  # the foam's values are a model's that does not hold
        for row in rows:
            if row["table"] == "sponge" and row["determined"]:
                row["determined"] = False
                row["trials_to_determine"] = None
                row["note"] = ("the cell is not represented by the twin: a value of a foam "
                               "model the records refute is not a measurement")
    return rows


SELF_STANDING = frozenset({"hysteresis_loss"})
"""Amplitudes the records pin without their scale: the hysteresis's branch gap h is reached
within a few d_h of a reversal, and the learner's steps are longer than that."""
PER_UNIT = {"passes": "pass"}
"""A scale's unit in "per <unit>"."""


def amplitudes_need_their_scales(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """An amplitude is determined only with its scale (``SCALE_OF``), even when it is ~0.

    With a wear's time constant held or loose, the records pin the curve's start, the
    initial rate (amplitude / time constant) per pass, not the amplitude: a softening of
    0.33 at a held 150 passes is the records' slope, not the foam's final softening.
    Such an amplitude is reported not determined, with the rate the records do give.
    Rows are changed in place and returned.
    """
    by_name = {row["name"]: row for row in rows}
    for amplitude, scale in SCALE_OF.items():
        if amplitude in SELF_STANDING:
            continue
        row, scale_row = by_name.get(amplitude), by_name.get(scale)
        if row is None or scale_row is None or not row["determined"] or scale_row["determined"]:
            continue
        # ~0 too: at a held or loose scale it is an initial rate of ~0 at that scale, not
        # "none of it" (hidden cell 03 of seed 1: softening 0.005 +- 0.017 "determined",
        # truth 0.19 over a time constant the 60 trials do not reach)
        rate = row["value"] / scale_row["value"]
        sigma = (row["sigma"] or 0.0) / scale_row["value"]
        row["determined"] = False
        row["trials_to_determine"] = scale_row.get("trials_to_determine")
        row["note"] = (f"determined only with its scale {scale} ({_fmt(scale_row['value'])} "
                       f"{scale_row['unit']}, not determined): the records give the initial "
                       f"rate {_fmt(rate)} ± {_fmt(sigma)} {row['unit']} per "
                       f"{PER_UNIT.get(scale_row['unit'], scale_row['unit'])}, not the amplitude"
                       + ("; " + row["note"] if "note" in row else ""))
    return rows


def twin_document(fit: TwinFit, source: RunSource) -> dict[str, Any]:
    """twin.json's content."""
    held = fit.heldout
    per_trial = []
    for i, trial in enumerate(held.trial.tolist()):
        use = held.is_step[i] & held.has_burst[i]
        residual = (fit.heldout_predicted[i] - held.mean_n[i])[use]
        per_trial.append({"trial": int(trial), "rms_n": float(np.sqrt(np.mean(residual**2)))
                          if residual.size else None})
    return {
        "represented": fit.represented,
        "verdict": fit.reason,
        "threshold_n": fit.threshold_n,
        "runs": [str(p) for p in source.run_dirs],
        "trials": {"fitted": fit.train.trial.tolist(), "held_out": held.trial.tolist(),
                   "held_out_share": HOLD_OUT},
        "member": fit.chosen.member.name,
        "choice": fit.choice,
        "members": [
            {"name": m.member.name, "text": m.member.text, "free": m.free,
             "held": list(m.held), "train_cost": m.train_cost, "eligible": m.eligible,
             "note": m.note,
             "train_rms_n": m.train_rms_n, "heldout_rms_n": m.heldout_rms_n, "bic": m.bic}
            for m in fit.members
        ],
        "parameters": parameter_rows(fit),
        "sponge": dict(fit.sponge),
        "residuals": {"train_rms_n": fit.chosen.train_rms_n,
                      "heldout_rms_n": fit.chosen.heldout_rms_n,
                      "heldout_per_trial": per_trial,
                      "arm_rms_s": fit.arm.rms_s, "arm_moves": fit.arm.moves,
                      "tick_grid": (None if fit.arm.grid is None
                                    else dataclasses.asdict(fit.arm.grid))},
        "sensor": {"colour_phi_upper_bound": fit.sensor.colour_phi,
                   "tares": fit.sensor.tares, "samples": fit.sensor.samples,
                   "drift_source": fit.sensor.drift_source},
        "diagnostics": fit.diagnostics,
    }


def _fmt(value: float | None) -> str:
    if value is None or math.isnan(value):
        return "—"
    if math.isinf(value):
        return "∞"
    return f"{value:.4g}"


BIAS_NOTE = (
    "The sensor's bias is not fitted as a parameter of the cell: it drifts as a random walk "
    "(the rate above) and is profiled out, constant within a trial and 0 at each tare. On the "
    "fitted trials it is estimated from all their reads; on the held-out trials ONLY from "
    "their free-space reads (the bursts where the twin predicts no contact) and the walk from "
    "the last fitted trial, never from the in-contact readings being predicted: the sensor's "
    "zero is not a property of the cell; the twin reads it from the run's free-space "
    "readings as a tare would."
)


def twin_markdown(document: dict[str, Any]) -> str:
    """twin.md: the verdict, the members, every parameter, the residuals."""
    lines = ["# Twin of the cell", ""]
    if document["represented"]:
        lines += [f"Represented by the member **{document['member']}**: {document['verdict']}."]
    else:
        lines += [f"**This cell is not represented by the twin:** {document['verdict']}. "
                  "No twin.toml was written."]
    trials = document["trials"]
    lines += ["", f"Fitted on {len(trials['fitted'])} trials; the last "
              f"{len(trials['held_out'])} ({trials['held_out_share']:.0%}) held out.", "",
              "## Members (a richer one only when it wins on the held-out trials and what it "
              "adds is determined)", "",
              "| member | parameters | train RMS (N) | held-out RMS (N) | BIC |",
              "|---|---|---|---|---|"]
    for m in document["members"]:
        dropped = "" if m.get("eligible", True) else " **dropped**"
        lines.append(f"| {m['name']} ({m['text']}){dropped} | {m['free']} "
                     f"| {_fmt(m['train_rms_n'])} "
                     f"| {_fmt(m['heldout_rms_n'])} | {_fmt(m['bic'])} |")
    notes = [f"- {m['name']}: {m['note']}" for m in document["members"] if m.get("note")]
    notes += [f"- {note}" for note in document.get("choice", [])]
    lines += ["", *notes] if notes else []
    held = [p["name"] for p in document["parameters"] if "held at the base" in p.get("note", "")]
    lines += ["", "## Parameters", "",
              "A parameter is determined when its 1-sigma uncertainty is at most 3 % of its "
              "value or the absolute bound shown; the ±1σ is the larger of the fit's "
              "(Jacobian) and the spread of refits without a block of trials or on the low "
              "and high forces apart (docs/twin-fit.md).", ""]
    if held:
        lines += [f"Held at the base config's value (twin.toml), as the records do not "
                  f"determine them: {', '.join(held)}. A wear's or relaxation's time scale is "
                  "held first and its amplitude refitted, so the amplitude is then the "
                  "initial rate at that time scale.", ""]
    lines += [
              "| table | parameter | value | ±1σ | determined | trials to determine | note |",
              "|---|---|---|---|---|---|---|"]
    for p in document["parameters"]:
        verdict = "yes" if p["determined"] else f"no (needs ±{_fmt(p['determined_below'])})"
        value = _fmt(p["value"]) if p["determined"] else f"({_fmt(p['value'])})"
        need = p.get("trials_to_determine")
        lines.append(f"| {p['table']} | {p['name']} ({p['unit']}) | {value} | "
                     f"{_fmt(p['sigma'])} | {verdict} | {need if need is not None else '—'} | "
                     f"{p.get('note', '')} |")
    res = document["residuals"]
    lines += ["", "Values in brackets are not determined by the records: they are what the "
              "fit left, not a measurement.", "", "## Residuals", "",
              f"- control steps, fitted trials: RMS {_fmt(res['train_rms_n'])} N",
              f"- control steps, held-out trials: RMS {_fmt(res['heldout_rms_n'])} N "
              f"(bar: {_fmt(document['threshold_n'])} N)",
              f"- arm, command to in position: RMS {_fmt(res['arm_rms_s'])} s over "
              f"{res['arm_moves']} moves",
              _grid_line(res.get("tick_grid")),
              f"- sensor noise colour: AR(1) per sample at most "
              f"{_fmt(document['sensor']['colour_phi_upper_bound'])}", "",
              BIAS_NOTE, ""]
    lines += ["| held-out trial | RMS (N) |", "|---|---|"]
    lines += [f"| {t['trial']} | {_fmt(t['rms_n'])} |" for t in res["heldout_per_trial"]]
    for note in document["diagnostics"]:
        lines.append(f"- {note}")
    lines += ["", "![recorded vs predicted force, held-out trials](twin_heldout.png)", ""]
    return "\n".join(lines)


def _grid_line(grid: dict[str, float] | None) -> str:
    """Where the moves' in-position times came from (:mod:`~forcelearn.tools.twin.tick_grid`)."""
    if grid is None:
        return ("- moves' in-position: the timing model's mean over the controller's tick "
                "(the records do not place them on its grid)")
    return (f"- moves' in-position: each on the controller's {grid['tick_s'] * 1000:.0f} ms "
            f"tick (grid phase {grid['phase_s'] * 1000:.2f} ms, command to counted "
            f"{grid['delay_s'] * 1000:.2f} ms, {grid['after_burst_s'] * 1000:+.2f} ms after "
            f"a burst read; inside the detection window on {grid['share']:.1%} of "
            f"{grid['moves']} moves)")


def twin_config(fit: TwinFit, source: RunSource) -> dict[str, Any]:
    """twin.toml: the run's config with the devices emulated and the fitted physics."""
    raw = {k: (dict(v) if isinstance(v, dict) else v) for k, v in source.raw_config.items()}
    config = source.config
    robot_entry, sensor_entry = robot_kind(config.robot_kind), sensor_kind(config.sensor_kind)
    robot = {"kind": robot_entry.name, robot_entry.emulated_key: "emulated"}
    sensor = {"kind": sensor_entry.name, sensor_entry.emulated_key: "emulated"}
    for key in sensor_entry.learner_keys:
        if key in raw.get("sensor", {}):
            sensor[key] = raw["sensor"][key]
    raw.pop("calibration", None)  # the site's calibration file is of the real sensor
    safety = dict(raw.get("safety", {}))
    safety.pop("stale_sensor_s", None)  # the emulated sensor's watchdog default applies
    # A new [emulator]: the run's own (an emulated run's hidden truth) is not carried over.
    emulator: dict[str, Any] = {"time_scale": 0.0, "profile": "realistic"}
    emulator["sponge"] = {k: float(v) for k, v in fit.sponge.items()}
    arm = {p.name: fit.arm.values[p.name] for p in ARM}
    arm["start_delay_s"] = fit.base_start_delay_s  # the twin's emulated link adds its own time
    emulator["arm"] = arm
    base_sensor: Any = sensor_entry.model(EmulatorConfig())
    sensor_model: dict[str, Any] = {}
    noise = list(base_sensor.noise_std)
    if math.isfinite(fit.sensor.noise_n):
        noise[:3] = [fit.sensor.noise_n] * 3
    sensor_model["noise_std"] = noise
    drift = list(base_sensor.bias_drift_per_sqrt_s)
    if drift_detected(fit.sensor.drift_n_per_sqrt_s, fit.sensor.drift_sigma):
        drift[:3] = [fit.sensor.drift_n_per_sqrt_s] * 3
    sensor_model["bias_drift_per_sqrt_s"] = drift
    emulator["sensor"] = sensor_model
    out = {**raw, "robot": robot, "sensor": sensor, "emulator": emulator}
    if safety:
        out["safety"] = safety
    return out


def write_figure(fit: TwinFit, path: Path) -> None:
    """Recorded vs predicted force per control step, one panel per held-out trial."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    held = fit.heldout
    count = min(held.trials, 12)
    cols = min(4, count)
    rows = math.ceil(count / cols)
    figure, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.6 * rows), squeeze=False)
    for k in range(rows * cols):
        ax = axes[k // cols][k % cols]
        if k >= count:
            ax.axis("off")
            continue
        i = held.trials - count + k
        use = held.is_step[i] & held.has_burst[i]
        steps = np.arange(1, int(use.sum()) + 1)
        ax.plot(steps, held.mean_n[i][use], "o", ms=3, label="recorded")
        ax.plot(steps, fit.heldout_predicted[i][use], "-", label="twin")
        ax.set_title(f"trial {int(held.trial[i])}", fontsize=9)
        ax.set_xlabel("step")
        ax.set_ylabel("force (N)")
    axes[0][0].legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=90)
    plt.close(figure)


def write_report(fit: TwinFit, source: RunSource, out: Path, figure: bool = True
                 ) -> dict[str, Any]:
    """Write twin.json, twin.md and the figure beside ``out``; twin.toml only if represented.

    ``figure`` False: no twin_heldout.png (a study's many fits read only twin.json).
    """
    folder = out.parent
    folder.mkdir(parents=True, exist_ok=True)
    document = twin_document(fit, source)
    (folder / "twin.json").write_text(json.dumps(document, indent=2, default=_plain))
    (folder / "twin.md").write_text(twin_markdown(document))
    if figure:
        write_figure(fit, folder / "twin_heldout.png")
    if fit.represented:
        header = "".join(
            f"# {p['table']}.{p['name']} is NOT determined by the records (±{_fmt(p['sigma'])}"
            f" {p['unit']}): {p.get('note', 'the fit left this value')}\n"
            for p in document["parameters"] if not p["determined"]
        )
        body = tomli_w.dumps(twin_config(fit, source))
        out.write_text("# A twin of the cell written by forcelearn twin; see twin.md.\n"
                       + header + "\n" + body)
    return document


def _plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return dataclasses.asdict(value)
    if isinstance(value, np.generic):
        return value.item()
    return str(value)
