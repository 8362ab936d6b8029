// The live page: merges the server's frames into one state and redraws the panels.
// It only reads (/api/events, /api/state); it has no way to send anything to the run.
"use strict";

const COLUMNS = ["index", "phase", "steps", "failed", "mean_r", "force_rms_n", "start_force_n", "cell_time_s"];
const state = { meta: null, trials: {}, marks: {}, status: {}, events: [], version: 0 };
let pending = false;

function merge(frame) {
  const since = frame.trials.since;
  for (const name of COLUMNS) {
    const kept = since === 0 ? [] : (state.trials[name] || []).slice(0, since);
    state.trials[name] = kept.concat(frame.trials[name] || []);
  }
  for (const key of ["meta", "present", "previous", "best", "first", "marks", "status", "events", "version"]) {
    state[key] = frame[key];
  }
  if (!pending) { pending = true; requestAnimationFrame(render); }
}

const col = (trace, name) => (trace ? trace.rows.map((r) => r[name]) : []);
const fmt = (v, digits) => (v === null || v === undefined ? "–" : Number(v).toFixed(digits));
const label = (trace, what) => `${what} (trial ${trace.trial + 1})`;

function clock(seconds) {
  if (seconds === null || seconds === undefined) return "–";
  const s = Math.floor(seconds), h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60);
  return `${h}:${String(m).padStart(2, "0")}:${String(s % 60).padStart(2, "0")}`;
}

function render() {
  pending = false;
  const meta = state.meta, status = state.status, marks = state.marks;
  if (!meta) return;
  document.body.classList.add(meta.task);
  document.getElementById("task").textContent = meta.task;
  document.getElementById("source").textContent = meta.source === "view" ? "view of a run directory" : "live run";
  const trial = Math.min(status.trial + 1, status.trials_target);
  set("s-trial", `${trial} of ${status.trials_target} (${status.trials_done} done)`);
  set("s-phase", status.phase || "–");
  set("s-cell", status.cell_time_s ? clock(status.cell_time_s) : "–");
  set("s-wall", clock(status.wall_s));
  set("s-rate", fmt(status.steps_per_s, 0));
  set("s-switch", marks.phase_switch_trial === null ? "not yet" : `after trial ${marks.phase_switch_trial + 1}`);
  set("s-converged", marks.converged_trial === null ? "not yet" : `at trial ${marks.converged_trial + 1}`);
  set("s-failures", String(marks.failures));
  const safety = status.last_safety;
  const safetyCell = document.getElementById("s-safety");
  safetyCell.textContent = safety ? `${safety.kind} at trial ${safety.trial + 1}, step ${safety.step}: ${safety.message}` : "none";
  safetyCell.classList.toggle("alert", Boolean(safety));
  set("s-devices", (meta.devices || []).join("; ") || "–");
  set("s-state", status.error ? `stopped: ${status.error}` : status.finished ? "finished" : "running");
  set("s-dropped", String(status.dropped_updates));
  if (meta.task === "contour") drawPath(); else { drawForce(); drawY(); drawInitial(); }
  drawCurve();
  document.body.dataset.trial = String(status.trial);
  document.body.dataset.trialsDone = String(status.trials_done);
  document.body.dataset.version = String(state.version);
  document.dispatchEvent(new CustomEvent("live-rendered", { detail: { trial: status.trial } }));
}

function set(id, text) { document.getElementById(id).textContent = text; }

function drawForce() {
  const m = state.meta, d = m.desired_force_n, series = [];
  const add = (trace, what, color, dash, width) => {
    if (trace && trace.rows.length) series.push({ x: col(trace, "step"), y: col(trace, "force_n"), color, dash, width, label: label(trace, what), marker: "dot" });
  };
  add(state.best, "best", "#2e7d32", [2, 3], 1.2);
  add(state.previous, "previous", "#9aa1ab", [6, 3], 1.2);
  add(state.present, "present", "#1565c0", [], 2);
  Plot.draw(document.getElementById("plot-force"), {
    xlabel: "step", ylabel: "contact force (N)", xlim: [0.5, m.steps_per_trial + 0.5], series,
    band: d === null ? null : { y0: d * (1 - m.band), y1: d * (1 + m.band) },
    hlines: d === null ? [] : [{ y: d, color: "#1d2430", width: 1, label: `desired ${d.toFixed(2)} N ±${m.band * 100} %` }],
  });
}

function drawY() {
  const series = [], path = state.meta.task === "path";
  const mean = path ? "mean_offset_mm" : "mean_y_mm";
  const add = (trace, what, color) => {
    if (!trace || !trace.rows.length) return;
    series.push({ x: col(trace, "step"), y: col(trace, mean), color, marker: "dot", label: label(trace, `${what}: mean`) });
    series.push({ x: col(trace, "step"), y: col(trace, "command_0"), color, dash: [5, 3], width: 1, label: `${what}: searched` });
  };
  add(state.previous, "previous", "#9aa1ab");
  add(state.present, "present", "#1565c0");
  const p = state.present;
  if (p && p.rows.length && p.rows[0].map_centre_y_mm !== undefined) {
    const shift = p.rows[p.rows.length - 1].map_shift_mm || 0;
    series.push({ x: col(p, "step"), y: col(p, "map_centre_y_mm"), color: "#6d4c41", dash: [2, 2], width: 1, label: `map centre (wear shift ${shift.toFixed(2)} mm)` });
  }
  Plot.draw(document.getElementById("plot-y"), {
    xlabel: path ? "point" : "step", ylabel: path ? "offset along the force axis (mm)" : "Y command (mm)",
    xlim: [0.5, state.meta.steps_per_trial + 0.5], series,
  });
}

function drawCurve() {
  const t = state.trials, marks = state.marks, m = state.meta;
  const x = t.index.map((i) => i + 1);
  const ok = t.force_rms_n.map((v, i) => (t.failed[i] ? null : v));
  const bad = t.force_rms_n.map((v, i) => (t.failed[i] ? v : null));
  const vlines = [];
  if (marks.phase_switch_trial !== null) vlines.push({ x: marks.phase_switch_trial + 1, color: "#c62828", dash: [3, 3], label: "phase switch" });
  if (marks.converged_trial !== null) vlines.push({ x: marks.converged_trial + 1, color: "#2e7d32", dash: [6, 3], label: "converged" });
  const hlines = m.desired_force_n === null ? [] : [{ y: m.band * Math.abs(m.desired_force_n), color: "#2e7d32", width: 1, label: "5 % of desired" }];
  Plot.draw(document.getElementById("plot-curve"), {
    xlabel: "trial", ylabel: "force RMS error (N)", xlim: [0, Math.max(m.trials_target, 1) + 1],
    series: [
      { x, y: ok, color: "#1565c0", width: 0, marker: "dot", label: "completed trial" },
      { x, y: bad, color: "#c62828", width: 0, marker: "x", label: "failed trial" },
    ],
    hlines, vlines,
  });
}

function drawInitial() {
  const t = state.trials;
  Plot.draw(document.getElementById("plot-initial"), {
    xlabel: "repetition", ylabel: "initial contact force (N)", xlim: [0, Math.max(state.meta.trials_target, 1) + 1],
    series: [{ x: t.index.map((i) => i + 1), y: t.start_force_n, color: "#6a1b9a", width: 1, marker: "dot", size: 1.5 }],
  });
}

function drawPath() {
  const g = state.meta.geometry || {}, series = [];
  if (g.centre_m) {
    const n = 181, xs = [], ys = [];
    for (let i = 0; i < n; i++) {
      const a = (2 * Math.PI * i) / (n - 1);
      xs.push(g.centre_m[0] + g.radius_m * Math.cos(a)); ys.push(g.centre_m[1] + g.radius_m * Math.sin(a));
    }
    series.push({ x: xs, y: ys, color: "#9aa1ab", width: 1, label: "surface (circle)" });
  }
  for (const [trace, what, color] of [[state.previous, "previous", "#f57c00"], [state.present, "present", "#1565c0"]]) {
    if (trace && trace.rows.length) series.push({ x: col(trace, "tip_x_m"), y: col(trace, "tip_y_m"), color, marker: "dot", label: label(trace, what) });
  }
  const tips = series.slice(1);
  const xs = tips.flatMap((s) => s.x), ys = tips.flatMap((s) => s.y);
  const pad = 0.15;
  const lim = (v) => (v.length ? [Math.min(...v) - pad, Math.max(...v) + pad] : null);
  Plot.draw(document.getElementById("plot-path"), {
    xlabel: "x (m)", ylabel: "y (m)", equal: true, series, xlim: lim(xs), ylim: lim(ys),
  });
}

function connect() {
  const badge = document.getElementById("connection");
  const source = new EventSource("/api/events");
  source.addEventListener("state", (e) => {
    merge(JSON.parse(e.data));
    const ended = state.status.finished;
    badge.textContent = ended ? "run ended" : "live"; badge.className = `tag ${ended ? "ended" : "live"}`;
  });
  source.onerror = () => {
    if (state.status.finished) { source.close(); return; }
    badge.textContent = "reconnecting"; badge.className = "tag lost";
  };
}

window.addEventListener("resize", () => { if (!pending) { pending = true; requestAnimationFrame(render); } });
connect();
