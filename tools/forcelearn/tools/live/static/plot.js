// forcelearn's own small canvas plotter: lines, markers, horizontal/vertical marks, a band.
// No library, no network: the page must work on an offline cell PC.
"use strict";

const Plot = (() => {
  function niceStep(span, count) {
    const raw = span / Math.max(count, 1);
    const mag = Math.pow(10, Math.floor(Math.log10(raw)));
    const norm = raw / mag;
    return (norm < 1.5 ? 1 : norm < 3 ? 2 : norm < 7 ? 5 : 10) * mag;
  }

  function extent(values, fallback) {
    let lo = Infinity, hi = -Infinity;
    for (const v of values) {
      if (v === null || !Number.isFinite(v)) continue;
      if (v < lo) lo = v;
      if (v > hi) hi = v;
    }
    if (lo === Infinity) return fallback;
    if (lo === hi) { lo -= 1; hi += 1; }
    const pad = (hi - lo) * 0.05;
    return [lo - pad, hi + pad];
  }

  function format(v, step) {
    const digits = Math.max(0, -Math.floor(Math.log10(step) + 1e-9));
    return v.toFixed(Math.min(digits, 4));
  }

  // opts: {xlabel, ylabel, xlim, ylim, equal, band: {y0, y1, color},
  //        series: [{x, y, color, width, dash, marker, label}],
  //        hlines: [{y, color, dash, label}], vlines: [{x, color, dash, label}]}
  function draw(canvas, opts) {
    const ratio = window.devicePixelRatio || 1;
    const width = canvas.clientWidth || 400, height = canvas.clientHeight || 260;
    if (canvas.width !== width * ratio || canvas.height !== height * ratio) {
      canvas.width = width * ratio;
      canvas.height = height * ratio;
    }
    const ctx = canvas.getContext("2d");
    ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
    ctx.clearRect(0, 0, width, height);
    const series = opts.series || [], hlines = opts.hlines || [], vlines = opts.vlines || [];
    const xs = [], ys = [];
    for (const s of series) { xs.push(...s.x); ys.push(...s.y); }
    for (const h of hlines) ys.push(h.y);
    for (const v of vlines) xs.push(v.x);
    if (opts.band) ys.push(opts.band.y0, opts.band.y1);
    let [x0, x1] = opts.xlim || extent(xs, [0, 1]);
    let [y0, y1] = opts.ylim || extent(ys, [0, 1]);
    const left = 56, right = 10, top = 10, bottom = 34;
    const pw = width - left - right, ph = height - top - bottom;
    if (opts.equal) {
      const sx = (x1 - x0) / pw, sy = (y1 - y0) / ph, s = Math.max(sx, sy);
      const cx = (x0 + x1) / 2, cy = (y0 + y1) / 2;
      x0 = cx - s * pw / 2; x1 = cx + s * pw / 2; y0 = cy - s * ph / 2; y1 = cy + s * ph / 2;
    }
    const px = (x) => left + (x - x0) / (x1 - x0) * pw;
    const py = (y) => top + (1 - (y - y0) / (y1 - y0)) * ph;

    ctx.font = "11px system-ui, sans-serif";
    ctx.strokeStyle = "#e3e6ea"; ctx.fillStyle = "#6b7380"; ctx.lineWidth = 1;
    const xstep = niceStep(x1 - x0, Math.max(2, Math.floor(pw / 70)));
    const ystep = niceStep(y1 - y0, Math.max(2, Math.floor(ph / 40)));
    ctx.textAlign = "center"; ctx.textBaseline = "top";
    for (let x = Math.ceil(x0 / xstep) * xstep; x <= x1; x += xstep) {
      ctx.beginPath(); ctx.moveTo(px(x), top); ctx.lineTo(px(x), top + ph); ctx.stroke();
      ctx.fillText(format(x, xstep), px(x), top + ph + 3);
    }
    ctx.textAlign = "right"; ctx.textBaseline = "middle";
    for (let y = Math.ceil(y0 / ystep) * ystep; y <= y1; y += ystep) {
      ctx.beginPath(); ctx.moveTo(left, py(y)); ctx.lineTo(left + pw, py(y)); ctx.stroke();
      ctx.fillText(format(y, ystep), left - 4, py(y));
    }
    ctx.textAlign = "center"; ctx.textBaseline = "bottom";
    if (opts.xlabel) ctx.fillText(opts.xlabel, left + pw / 2, height - 1);
    if (opts.ylabel) {
      ctx.save(); ctx.translate(11, top + ph / 2); ctx.rotate(-Math.PI / 2);
      ctx.textBaseline = "middle"; ctx.fillText(opts.ylabel, 0, 0); ctx.restore();
    }
    ctx.save();
    ctx.beginPath(); ctx.rect(left, top, pw, ph); ctx.clip();
    if (opts.band) {
      ctx.fillStyle = opts.band.color || "rgba(46,125,50,0.13)";
      const a = py(opts.band.y1), b = py(opts.band.y0);
      ctx.fillRect(left, a, pw, b - a);
    }
    for (const h of hlines) line(ctx, h, [[x0, h.y], [x1, h.y]], px, py);
    for (const v of vlines) line(ctx, v, [[v.x, y0], [v.x, y1]], px, py);
    for (const s of series) {
      const points = s.x.map((x, i) => [x, s.y[i]]);
      if (s.width !== 0) line(ctx, s, points, px, py);
      if (s.marker) markers(ctx, s, points, px, py);
    }
    ctx.restore();
    ctx.strokeStyle = "#9aa1ab"; ctx.strokeRect(left, top, pw, ph);
    const labelled = [...series, ...hlines, ...vlines].filter((s) => s.label);
    const marks = [];
    for (const s of series) s.x.forEach((x, i) => marks.push([px(x), py(s.y[i])]));
    for (const h of hlines) for (let i = 0; i <= 20; i++) marks.push([left + pw * i / 20, py(h.y)]);
    for (const v of vlines) for (let i = 0; i <= 20; i++) marks.push([px(v.x), top + ph * i / 20]);
    legend(ctx, labelled, { left, top, pw, ph }, marks);
    canvas.dataset.drawn = String((Number(canvas.dataset.drawn) || 0) + 1);
  }

  function line(ctx, s, points, px, py) {
    ctx.strokeStyle = s.color || "#1f77b4"; ctx.lineWidth = s.width || 1.5;
    ctx.setLineDash(s.dash || []);
    ctx.beginPath();
    let pen = false;
    for (const [x, y] of points) {
      if (y === null || x === null || !Number.isFinite(y)) { pen = false; continue; }
      if (pen) ctx.lineTo(px(x), py(y)); else ctx.moveTo(px(x), py(y));
      pen = true;
    }
    ctx.stroke(); ctx.setLineDash([]);
  }

  function markers(ctx, s, points, px, py) {
    ctx.strokeStyle = ctx.fillStyle = s.color || "#1f77b4"; ctx.lineWidth = 1.5;
    const r = s.size || 2.2;
    for (const [x, y] of points) {
      if (y === null || !Number.isFinite(y)) continue;
      const cx = px(x), cy = py(y);
      if (s.marker === "x") {
        ctx.beginPath();
        ctx.moveTo(cx - r - 1, cy - r - 1); ctx.lineTo(cx + r + 1, cy + r + 1);
        ctx.moveTo(cx - r - 1, cy + r + 1); ctx.lineTo(cx + r + 1, cy - r - 1); ctx.stroke();
      } else {
        ctx.beginPath(); ctx.arc(cx, cy, r, 0, 2 * Math.PI); ctx.fill();
      }
    }
  }

  // The corner of the plot area for a w x h legend that hides the fewest marks ([x, y]
  // in px: data points, and points along the horizontal and vertical lines); the first
  // of top right, top left, bottom right, bottom left when several tie. Its top-left [x, y].
  function legendCorner(w, h, area, marks) {
    const corners = [
      [area.left + area.pw - 6 - w, area.top + 4], [area.left + 6, area.top + 4],
      [area.left + area.pw - 6 - w, area.top + area.ph - 6 - h], [area.left + 6, area.top + area.ph - 6 - h],
    ];
    const hidden = ([x, y]) => marks.filter(([mx, my]) =>
      Number.isFinite(my) && mx >= x && mx <= x + w && my >= y && my <= y + h).length;
    let best = corners[0], least = hidden(best);
    for (const corner of corners.slice(1)) {
      const count = hidden(corner);
      if (count < least) { best = corner; least = count; }
    }
    return best;
  }

  function legend(ctx, items, area, marks) {
    if (!items.length) return;
    ctx.font = "11px system-ui, sans-serif";
    const w = Math.max(...items.map((s) => ctx.measureText(s.label).width)) + 30;
    const h = items.length * 14 + 4;
    const [x, y] = legendCorner(w, h, area, marks);
    ctx.fillStyle = "rgba(255,255,255,0.85)";
    ctx.fillRect(x, y, w, h);
    ctx.textAlign = "left"; ctx.textBaseline = "middle";
    items.forEach((s, i) => {
      const yy = y + 8 + i * 14;
      ctx.strokeStyle = ctx.fillStyle = s.color || "#1f77b4";
      ctx.setLineDash(s.dash || []); ctx.lineWidth = s.width || 1.5;
      if (s.width === 0 && s.marker === "x") {
        ctx.beginPath(); ctx.moveTo(x + 10, yy - 3); ctx.lineTo(x + 16, yy + 3);
        ctx.moveTo(x + 10, yy + 3); ctx.lineTo(x + 16, yy - 3); ctx.stroke();
      } else if (s.width === 0) { ctx.beginPath(); ctx.arc(x + 13, yy, 2.5, 0, 2 * Math.PI); ctx.fill(); }
      else { ctx.beginPath(); ctx.moveTo(x + 4, yy); ctx.lineTo(x + 22, yy); ctx.stroke(); }
      ctx.setLineDash([]); ctx.fillStyle = "#1d2430";
      ctx.fillText(s.label, x + 26, yy);
    });
  }

  return { draw, legendCorner };
})();
