// sewmech's interactive page: plain JavaScript, drawn on canvases (docs/serve.md).
// The server computes one turn per design (POST .../turn); this page animates it locally.
"use strict";

const $ = (id) => document.getElementById(id);
const S = {
  token: null, machine: null, params: {}, values: {}, turn: null, checks: null,
  k: 0, playing: true, inFlight: false, pending: false, checksTimer: null, view: null,
  edited: 0,          // counts edits: an answer older than the newest edit is not the last word
  latency: [],        // slider-to-redraw times, ms (the benchmark reads them)
  redraws: 0,
};
window.sewmech = S;

// ---- requests -------------------------------------------------------------------------------
async function api(path, body, raw) {
  const opts = body === undefined && raw === undefined ? {} : {
    method: "POST",
    headers: {"Content-Type": raw ? "application/octet-stream" : "application/json"},
    body: raw || JSON.stringify(body),
  };
  const r = await fetch(path, opts);
  const timing = (r.headers.get("server-timing") || "").match(/dur=([0-9.]+)/);
  if (timing) S.serverComputeMs = +timing[1];
  const type = r.headers.get("content-type") || "";
  const data = type.includes("json") ? await r.json() : await r.text();
  if (!r.ok) {
    const e = (data && data.error) || {where: path, what: `HTTP ${r.status}`, hint: ""};
    throw Object.assign(new Error(e.what), {info: e});
  }
  return data;
}

function showError(err) {
  const e = err.info || {where: "page", what: String(err.message || err), hint: ""};
  $("error-where").textContent = e.where ? e.where + ":" : "";
  $("error-what").textContent = e.what;
  $("error-hint").textContent = e.hint || "";
  $("error").hidden = false;
  $("status").textContent = "error";
}
function clearError() { $("error").hidden = true; }

// ---- machines -------------------------------------------------------------------------------
async function init() {
  const list = await api("/api/machines");
  const sel = $("machine");
  for (const m of list.machines) sel.add(new Option(m.name, m.name));
  sel.value = list.initial;
  sel.onchange = () => { if (sel.value) openMachine({machine: sel.value}); };
  $("upload").onchange = async (ev) => {
    const f = ev.target.files[0];
    ev.target.value = "";
    if (!f) return;
    const bytes = await f.arrayBuffer();
    try {
      const data = await api(`/api/upload?name=${encodeURIComponent(f.name)}`, undefined, bytes);
      await opened(data, true);
    } catch (err) { showError(err); }
  };
  $("filter").oninput = renderParams;
  $("play").onclick = () => { S.playing = !S.playing; $("play").textContent = S.playing ? "pause" : "play"; };
  $("scrub").oninput = () => { S.playing = false; $("play").textContent = "play"; S.k = +$("scrub").value; drawFrame(); };
  $("motion-kind").onchange = drawPlots;
  $("export-toml").onclick = () => download("export.toml");
  $("export-csv").onclick = () => download("curves.csv");
  // the drawing at the angle the page shows
  $("export-dxf").onclick = () => download("drawing.dxf", {phi_deg: S.turn ? S.turn.phi_deg[S.k] : 0});
  await openMachine({machine: list.initial});
  requestAnimationFrame(tick);
}

async function openMachine(body) {
  try { await opened(await api("/api/sessions", body)); } catch (err) { showError(err); }
}

async function opened(data, upload = false) {
  // answers still on their way for the machine before are not this one's: the edit count
  // moves on (so checks in flight are dropped) and checks not yet asked for are not asked
  S.edited += 1;
  clearTimeout(S.checksTimer);
  S.token = data.session;
  S.machine = data.machine;
  S.params = Object.fromEntries(data.machine.parameters.map((p) => [p.name, p]));
  S.values = {};
  S.turn = null; S.checks = null; S.view = null; S.k = 0;
  $("title").textContent = data.machine.title || data.machine.name;
  const sel = $("machine");
  for (const o of [...sel.options]) if (o.dataset.upload) o.remove();
  if (upload) {  // an opened file: shown in the list while it is open
    const o = new Option(`${data.machine.file} (opened file)`, "");
    o.dataset.upload = "1"; sel.add(o); sel.value = "";
  } else sel.value = data.machine.name;
  clearError();
  renderParams();
  await evaluate(performance.now());
}

// ---- parameters -----------------------------------------------------------------------------
function fmt(x, d = 3) {
  if (x === null || x === undefined || !isFinite(x)) return "–";
  const a = Math.abs(x);
  return a !== 0 && (a < 1e-3 || a >= 1e6) ? x.toExponential(2) : (+x.toFixed(d)).toString();
}

function paramRow(p) {
  const row = document.createElement("div");
  row.className = "param" + (p.name in S.values ? " changed" : "");
  row.dataset.name = p.name;
  const value = p.name in S.values ? S.values[p.name] : p.value;
  const label = document.createElement("label");
  label.innerHTML = `<span></span> <span class="where"></span>`;
  label.children[0].textContent = p.name;
  label.children[1].textContent = p.table;
  const range = document.createElement("input");
  range.type = "range";
  range.min = Math.min(p.slider_lo, value); range.max = Math.max(p.slider_hi, value);
  range.step = p.step; range.value = value;
  range.setAttribute("aria-label", p.name);
  const num = document.createElement("input");
  num.type = "number"; num.step = "any"; num.value = +(+value).toFixed(6);
  if (p.lo !== null) num.min = p.lo;
  if (p.hi !== null) num.max = p.hi;
  const unit = document.createElement("span");
  unit.className = "unit"; unit.textContent = p.unit;
  const set = (v, t0) => {
    if (!isFinite(v)) return;
    if (Math.abs(v - p.value) < 1e-12) delete S.values[p.name]; else S.values[p.name] = v;
    row.classList.toggle("changed", p.name in S.values);
    S.edited += 1;
    schedule(t0);
  };
  range.oninput = (ev) => { num.value = range.value; set(+range.value, ev.timeStamp || performance.now()); };
  num.onchange = (ev) => {
    const v = +num.value;
    if (v < +range.min) range.min = v;
    if (v > +range.max) range.max = v;
    range.value = v; set(v, ev.timeStamp || performance.now());
  };
  row.append(label, range, num, unit);
  return row;
}

function renderParams() {
  const q = $("filter").value.trim().toLowerCase();
  const setting = $("setting"), box = $("params");
  setting.replaceChildren(); box.replaceChildren();
  const all = Object.values(S.params);
  for (const p of all.filter((p) => p.kind === "input")) setting.append(paramRow(p));
  const shown = all.filter((p) => p.kind !== "input" &&
    (q ? (p.name + " " + p.table).toLowerCase().includes(q) : p.main || p.name in S.values));
  const head = document.createElement("div");
  head.className = "group";
  head.textContent = q ? `${shown.length} parameters match` :
    `main dimensions (${shown.length} of ${all.length - 1}; filter for every one)`;
  box.append(head);
  for (const p of shown.slice(0, 150)) box.append(paramRow(p));
}

// ---- evaluation -----------------------------------------------------------------------------
function schedule(t0) {
  S.pendingT0 = S.pendingT0 || t0;
  if (S.inFlight) { S.pending = true; return; }
  const t = S.pendingT0; S.pendingT0 = null;
  evaluate(t);
}

async function evaluate(t0) {
  S.inFlight = true;
  const edit = S.edited;
  const values = {...S.values};
  const token = S.token;
  $("status").textContent = "computing…";
  try {
    const t1 = performance.now();
    const turn = await api(`/api/sessions/${token}/turn`, {set: values});
    if (token !== S.token) return;  // another machine was opened meanwhile
    S.serverMs = performance.now() - t1;
    S.turn = turn; S.turnValues = values;
    clearError();
    if (S.k >= turn.phi_deg.length) S.k = 0;
    const t2 = performance.now();
    updateNumbers(); drawPlots(); drawFrame();
    S.drawMs = performance.now() - t2;
    S.redraws += 1;
    if (t0 !== undefined) S.latency.push(performance.now() - t0);
    $("status").textContent = `turn: ${S.serverComputeMs.toFixed(0)} ms on the server,` +
      ` ${S.serverMs.toFixed(0)} ms with the request, ${S.drawMs.toFixed(0)} ms to draw`;
    if (edit === S.edited) scheduleChecks(values);
  } catch (err) {
    if (token === S.token) showError(err);
  } finally {
    S.inFlight = false;
    if (S.pending) { S.pending = false; schedule(performance.now()); }
  }
}

function scheduleChecks(values) {
  clearTimeout(S.checksTimer);
  const token = S.token;
  S.checksTimer = setTimeout(async () => {
    const edit = S.edited;
    try {
      const c = await api(`/api/sessions/${token}/checks`, {set: values});
      if (edit === S.edited) { S.checks = c; renderChecks(); drawPlots(); }
    } catch (err) {
      if (edit === S.edited) {
        S.checks = {checks: [], events: [], error: err.info}; renderChecks(); showError(err);
      }
    }
  }, 120);
}

// the file name of a download header (RFC 6266): the UTF-8 name (filename*) where there is
// one, else the ASCII stand-in (filename), else `fallback`
function downloadName(header, fallback) {
  const utf8 = header.match(/filename\*=UTF-8''([^;\s]+)/i);
  if (utf8) { try { return decodeURIComponent(utf8[1]); } catch (e) { /* the stand-in */ } }
  const plain = header.match(/filename="([^"]*)"/);
  return plain && plain[1] ? plain[1] : fallback;
}

async function download(what, extra = {}) {
  try {
    const r = await fetch(`/api/sessions/${S.token}/${what}`, {
      method: "POST", headers: {"Content-Type": "application/json"},
      body: JSON.stringify({...extra, set: S.turnValues || {}})});
    if (!r.ok) throw Object.assign(new Error("export"), {info: (await r.json()).error});
    const blob = await r.blob();
    const a = document.createElement("a");
    a.href = URL.createObjectURL(blob);
    a.download = downloadName(r.headers.get("content-disposition") || "", what);
    document.body.append(a); a.click(); a.remove();
    setTimeout(() => URL.revokeObjectURL(a.href), 5000);
  } catch (err) { showError(err); }
}

// ---- numbers and tables ---------------------------------------------------------------------
function updateNumbers() {
  const t = S.turn, f = t.feed;
  $("stitch").textContent = f && !f.error && f.stitch_mm !== null ? `${f.stitch_mm.toFixed(2)} mm` : "–";
  $("stitch").dataset.value = f && !f.error ? f.stitch_mm : "";
  $("lift").textContent = f && !f.error && f.lift_mm !== null ? `${f.lift_mm.toFixed(2)} mm` : "–";
  if (t.dynamics) {
    const T = t.dynamics.torque_Nmm, F = t.dynamics.shaking_force_N;
    $("torque-max").textContent = `${fmt(Math.max(...T.map((x) => Math.abs(x ?? 0))) / 1000, 3)} N m`;
    $("shake-max").textContent = `${fmt(Math.max(...F.map((v) => Math.hypot(v[0] ?? 0, v[1] ?? 0))), 1)} N`;
    const mt = t.dynamics.mean_torque_Nmm, fl = t.dynamics.friction_loss_W;
    $("torque-mean").textContent = mt === null ? "–" : `${fmt(mt / 1000, 3)} N m`;
    $("friction-loss").textContent = fl === null ? "– (no [friction])" : `${fmt(fl, 2)} W`;
  } else {
    $("torque-max").textContent = $("shake-max").textContent = "– (no masses)";
    $("torque-mean").textContent = $("friction-loss").textContent = "– (no masses)";
  }
  renderVibration(t.dynamics && t.dynamics.vibration);
}

// the housing's levels at its control points (dB re 5e-8 m/s), live with every turn
function renderVibration(v) {
  const box = $("vibration");
  box.replaceChildren();
  if (!v) { box.hidden = true; return; }
  box.hidden = false;
  for (const [name, cp] of Object.entries(v)) {
    const div = document.createElement("div");
    div.className = "level";
    div.dataset.point = name;
    const b = document.createElement("b");
    const lv = cp.level_db;
    b.textContent = ["x", "y", "z"].map((ax) => `${ax} ${lv[ax] === null ? "–" : lv[ax].toFixed(1)}`).join("  ") + " dB";
    for (const ax of ["x", "y", "z"]) b.dataset[ax] = lv[ax] ?? "";
    div.append(`vibration at '${name}' `, b);
    box.append(div);
  }
}

function renderChecks() {
  const body = $("checks").tBodies[0];
  body.replaceChildren();
  const rows = [...((S.checks && S.checks.checks) || []), ...((S.turn && S.turn.thread && S.turn.thread.checks) || [])];
  for (const c of rows) {
    const tr = body.insertRow();
    tr.insertCell().textContent = c.check;
    const v = tr.insertCell(); v.className = "num"; v.textContent = `${c.shown ?? fmt(c.value, 3)} ${c.unit}`;
    tr.insertCell().textContent = c.expected;
    const r = tr.insertCell(); r.className = c.passed ? "pass" : "fail"; r.textContent = c.passed ? "pass" : "FAIL";
    const src = tr.insertCell(); src.textContent = c.source;  // keys of docs/references.md
    src.title = (c.references || []).map((r) => `[${r.key}] ${r.source} ${r.url}`.trim()).join("\n");
  }
  if (S.checks && S.checks.error) {
    const tr = body.insertRow(); const td = tr.insertCell(); td.colSpan = 5; td.className = "fail";
    td.textContent = `${S.checks.error.where || ""} ${S.checks.error.what}`;
  }
  const ev = $("events").tBodies[0];
  ev.replaceChildren();
  for (const e of (S.checks && S.checks.events) || []) {
    const tr = ev.insertRow();
    tr.insertCell().textContent = e.event;
    const v = tr.insertCell(); v.className = "num";
    v.textContent = e.value === null ? (e.error ? e.error.what : "–") : `${fmt(e.value, 2)} ${e.unit}`;
  }
}

// ---- drawing --------------------------------------------------------------------------------
const COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#17becf"];
const FONT = "10px system-ui, sans-serif", LABEL_FONT = "11px system-ui, sans-serif";

// a canvas sized to its box (CSS pixels x the device's pixel ratio), its height `aspect` times
// its width (default: the ratio of its width and height attributes in the HTML); every text
// drawn through text() is kept in canvas.labels as its box, so that nothing is drawn over
// another text or outside the canvas (the browser tests read them)
function ctxOf(canvas, aspect) {
  const dpr = window.devicePixelRatio || 1;
  if (!canvas._aspect) canvas._aspect = canvas.height / canvas.width;
  const w = canvas.clientWidth || canvas.width, h = Math.round(w * (aspect || canvas._aspect));
  if (canvas._w !== w || canvas._h !== h || canvas._dpr !== dpr) {
    canvas._w = w; canvas._dpr = dpr; canvas._h = h;
    canvas.width = Math.round(w * dpr); canvas.height = Math.round(h * dpr);
    canvas.style.height = h + "px";
  }
  const c = canvas.getContext("2d");
  c.setTransform(dpr, 0, 0, dpr, 0, 0);
  c.clearRect(0, 0, canvas._w, canvas._h);
  canvas.labels = [];
  return [c, canvas._w, canvas._h];
}

// the box a text would take, {x0, x1, y0, y1} (the font's full height, the text's advance)
function textBox(c, s, x, y, align = "left", baseline = "alphabetic", rotated = false) {
  c.textAlign = align; c.textBaseline = baseline;
  const m = c.measureText(s);
  const w = m.width, asc = m.fontBoundingBoxAscent, desc = m.fontBoundingBoxDescent;
  // the text's own frame: u along its baseline from its anchor, v down
  const u0 = align === "center" ? -w / 2 : align === "right" || align === "end" ? -w : 0;
  if (!rotated) return {x0: x + u0, x1: x + u0 + w, y0: y - asc, y1: y + desc};
  // turned a quarter counter-clockwise about the anchor (a y axis's label)
  return {x0: x - asc, x1: x + desc, y0: y - u0 - w, y1: y - u0};
}

function text(c, s, x, y, o = {}) {
  const box = textBox(c, s, x, y, o.align, o.baseline, o.rotated);
  // an optional text (a tick's label) that would touch another one is left out
  if (o.optional && c.canvas.labels.some((b) => overlaps(box, b, 1))) return null;
  if (o.rotated) {
    c.save(); c.translate(x, y); c.rotate(-Math.PI / 2); c.fillText(s, 0, 0); c.restore();
  } else {
    if (o.halo) {  // a white edge: the text reads over the lines it sits on
      c.save(); c.strokeStyle = "rgba(255, 255, 255, 0.9)"; c.lineWidth = 3; c.lineJoin = "round";
      c.strokeText(s, x, y); c.restore();
    }
    c.fillText(s, x, y);
  }
  c.canvas.labels.push({text: s, kind: o.kind || "", ...box});
  return box;
}

function overlaps(a, b, gap = 0) {
  return a.x0 < b.x1 + gap && b.x0 < a.x1 + gap && a.y0 < b.y1 + gap && b.y0 < a.y1 + gap;
}

function niceTicks(lo, hi, n = 5) {
  if (!(hi > lo)) { hi = lo + 1; lo -= 1; }
  const step0 = (hi - lo) / n, mag = Math.pow(10, Math.floor(Math.log10(step0)));
  const step = [1, 2, 2.5, 5, 10].map((m) => m * mag).find((s) => s >= step0);
  const out = [];
  for (let v = Math.ceil(lo / step) * step; v <= hi + 1e-9 * step; v += step) out.push(+v.toFixed(10));
  return out;
}

// the ticks of an axis whose labels do not run together: every k-th of `ticks`, k as small as
// the labels' widths (along the axis) allow in `length` pixels
function spacedTicks(c, ticks, length, lo, hi, size) {
  const inside = ticks.filter((t) => t >= lo && t <= hi);
  if (inside.length < 2) return inside;
  const need = Math.max(...inside.map(size)) + 8;
  const px = length * (inside[1] - inside[0]) / (hi - lo);
  const k = Math.max(1, Math.ceil(need / px));
  return inside.filter((_, i) => i % k === 0);
}

function yRange(series, hlines, axis) {
  let y0 = Infinity, y1 = -Infinity;
  for (const s of series) if ((s.axis || 0) === axis) for (const v of s.y) {
    if (v !== null) { y0 = Math.min(y0, v); y1 = Math.max(y1, v); }
  }
  for (const h of hlines || []) if ((h.axis || 0) === axis) { y0 = Math.min(y0, h.y); y1 = Math.max(y1, h.y); }
  if (!(y1 >= y0)) return null;
  const py = (y1 - y0) * 0.06 || Math.max(Math.abs(y0) * 0.06, 1);
  return [y0 - py, y1 + py];
}

// a line chart: series [{x, y, color, label, dash, axis}] (axis 1: the right-hand axis, in its
// own unit), options {xlabel, ylabel, y2label, cursor, equal, hlines, xticks, xrange, markers}.
// The margins are measured from the texts: the legend in rows above the plot (never cut), the
// tick labels spaced so that they never run together
function chart(canvas, series, o = {}) {
  const [c, W, H] = ctxOf(canvas);
  c.font = FONT; c.lineWidth = 1;
  const has2 = series.some((s) => s.axis === 1);
  const xs = [];
  for (const s of series) for (let i = 0; i < s.x.length; i++) if (s.x[i] !== null && s.y[i] !== null) xs.push(s.x[i]);
  if (!xs.length) {
    c.fillStyle = "#888";
    const lines = wrapText(c, o.empty || "nothing to show", W - 20);
    lines.forEach((ln, i) => text(c, ln, 10, H / 2 + i * 13, {kind: "note"}));
    return;
  }
  let x0 = o.xrange ? o.xrange[0] : Math.min(...xs), x1 = o.xrange ? o.xrange[1] : Math.max(...xs);
  if (!o.xrange) { const px = (x1 - x0) * 0.04 || 1; x0 -= px; x1 += px; }
  let [y0, y1] = yRange(series, o.hlines, 0) || [-1, 1];
  const r2 = has2 ? yRange(series, o.hlines, 1) || [-1, 1] : null;
  // the legend: entries in rows, as wide as the canvas allows
  const entries = series.map((s, j) => ({s, j})).filter((e) => e.s.label);
  const rows = [[]];
  let rowW = 0;
  const maxW = W - 12;
  for (const e of entries) {
    e.w = 14 + c.measureText(e.s.label).width;
    if (rows[rows.length - 1].length && rowW + 12 + e.w > maxW) { rows.push([]); rowW = 0; }
    rowW += (rows[rows.length - 1].length ? 12 : 0) + e.w;
    rows[rows.length - 1].push(e);
  }
  const lineH = 14, T = 6 + (entries.length ? rows.length * lineH : 4), B = 36;
  const fmtY = (t) => fmt(t, 3);
  const widest = (ticks, lo, hi) => Math.max(0, ...ticks.filter((t) => t >= lo && t <= hi)
    .map((t) => c.measureText(fmtY(t)).width));
  const yt2 = has2 ? niceTicks(r2[0], r2[1]) : [], wy2 = has2 ? widest(yt2, r2[0], r2[1]) : 0;
  // the left margin as wide as the y ticks' labels, which depend on the range, which (equal
  // scales) depends on the margin: until it settles
  const rx = [x0, x1], ry = [y0, y1];
  let L, pw, yt, wy = 0;
  const R = has2 ? 24 + wy2 : 10, ph = H - T - B;
  for (let pass = 0; pass < 4; pass++) {
    L = 24 + wy; pw = W - L - R;
    [x0, x1] = rx; [y0, y1] = ry;
    if (o.equal) {  // the same mm per pixel on both axes
      const sx = (x1 - x0) / pw, sy = (y1 - y0) / ph, sc = Math.max(sx, sy);
      const cx = (x0 + x1) / 2, cy = (y0 + y1) / 2;
      x0 = cx - sc * pw / 2; x1 = cx + sc * pw / 2; y0 = cy - sc * ph / 2; y1 = cy + sc * ph / 2;
    }
    yt = niceTicks(y0, y1);
    const w = widest(yt, y0, y1);
    if (w <= wy) break;
    wy = w;
  }
  const X = (x) => L + (x - x0) / (x1 - x0) * pw;
  const Ys = [(y) => T + (y1 - y) / (y1 - y0) * ph];
  if (has2) Ys.push((y) => T + (r2[1] - y) / (r2[1] - r2[0]) * ph);
  const Y = Ys[0];
  // the axes' labels first, then the ticks' labels, each left out where it would touch one
  c.font = LABEL_FONT; c.fillStyle = "#333";
  if (o.xlabel) text(c, o.xlabel, L + pw / 2, H - 3, {align: "center", baseline: "bottom", kind: "axis"});
  if (o.ylabel) text(c, fitText(c, o.ylabel, ph), 3, T + ph / 2, {align: "center", baseline: "top", rotated: true, kind: "axis"});
  if (has2 && o.y2label) {
    text(c, fitText(c, o.y2label, ph), W - 3, T + ph / 2, {align: "center", baseline: "bottom", rotated: true, kind: "axis"});
  }
  c.font = FONT;
  // grid and tick labels
  c.strokeStyle = "#e3e3e3"; c.fillStyle = "#555";
  const xticks = spacedTicks(c, o.xticks || niceTicks(x0, x1), pw, x0, x1, (t) => c.measureText(fmt(t, 2)).width);
  for (const t of xticks) {
    c.beginPath(); c.moveTo(X(t), T); c.lineTo(X(t), T + ph); c.stroke();
    text(c, fmt(t, 2), X(t), T + ph + 4, {align: "center", baseline: "top", kind: "tick", optional: true});
  }
  const fh = 12;  // a tick label's height, px
  for (const t of spacedTicks(c, yt, ph, y0, y1, () => fh)) {
    c.beginPath(); c.moveTo(L, Y(t)); c.lineTo(L + pw, Y(t)); c.stroke();
    text(c, fmtY(t), L - 4, Y(t), {align: "right", baseline: "middle", kind: "tick", optional: true});
  }
  if (has2) {
    for (const t of spacedTicks(c, yt2, ph, r2[0], r2[1], () => fh)) {
      c.strokeStyle = "#999"; c.beginPath(); c.moveTo(L + pw, Ys[1](t)); c.lineTo(L + pw + 3, Ys[1](t)); c.stroke();
      text(c, fmtY(t), L + pw + 5, Ys[1](t), {align: "left", baseline: "middle", kind: "tick", optional: true});
    }
  }
  c.strokeStyle = "#999"; c.strokeRect(L, T, pw, ph);
  c.font = FONT;
  for (const h of o.hlines || []) {
    const Yh = Ys[h.axis || 0];
    c.strokeStyle = h.color || "#000"; c.setLineDash(h.dash || []);
    c.beginPath(); c.moveTo(L, Yh(h.y)); c.lineTo(L + pw, Yh(h.y)); c.stroke(); c.setLineDash([]);
  }
  c.save(); c.beginPath(); c.rect(L, T, pw, ph); c.clip();
  series.forEach((s, j) => {
    const Yj = Ys[s.axis || 0];
    c.strokeStyle = s.color || COLORS[j % COLORS.length]; c.lineWidth = s.width || 1.5;
    c.setLineDash(s.dash || []);
    c.beginPath();
    let up = false;
    for (let i = 0; i < s.x.length; i++) {
      if (s.x[i] === null || s.y[i] === null) { up = false; continue; }
      if (up) c.lineTo(X(s.x[i]), Yj(s.y[i])); else { c.moveTo(X(s.x[i]), Yj(s.y[i])); up = true; }
    }
    if (s.closed && s.x.length) c.lineTo(X(s.x[0]), Yj(s.y[0]));
    c.stroke(); c.setLineDash([]);
  });
  for (const v of o.vlines || []) {
    c.strokeStyle = v.color || "#444"; c.setLineDash(v.dash || [3, 3]);
    c.beginPath(); c.moveTo(X(v.x), T); c.lineTo(X(v.x), T + ph); c.stroke(); c.setLineDash([]);
  }
  if (o.cursor !== undefined) {
    c.strokeStyle = "#000"; c.lineWidth = 1;
    c.beginPath(); c.moveTo(X(o.cursor), T); c.lineTo(X(o.cursor), T + ph); c.stroke();
  }
  for (const m of o.markers || []) {
    c.fillStyle = m.color || "#000"; c.beginPath(); c.arc(X(m.x), Y(m.y), 3.5, 0, 2 * Math.PI); c.fill();
  }
  c.restore();
  // the legend, above the plot
  rows.forEach((row, i) => {
    let lx = L;
    const ly = 6 + i * lineH + lineH / 2;
    for (const e of row) {
      const col = e.s.color || COLORS[e.j % COLORS.length];
      c.strokeStyle = col; c.lineWidth = 2; c.setLineDash(e.s.dash || []);
      c.beginPath(); c.moveTo(lx, ly); c.lineTo(lx + 10, ly); c.stroke(); c.setLineDash([]);
      c.fillStyle = "#333";
      text(c, e.s.label, lx + 14, ly, {baseline: "middle", kind: "legend"});
      lx += e.w + 12;
    }
  });
}

// a text cut to fit `width` px (an ellipsis where it was cut), for a label that must fit; an
// axis label's unit ("[mm]" at its end) is kept whole
function fitText(c, s, width) {
  if (c.measureText(s).width <= width) return s;
  const unit = (s.match(/ \[[^\]]*\]$/) || [""])[0];
  let name = s.slice(0, s.length - unit.length);
  while (name.length > 1 && c.measureText(name + "…" + unit).width > width) name = name.slice(0, -1);
  return name + "…" + unit;
}

function wrapText(c, s, width) {
  const out = [];
  let line = "";
  for (const word of s.split(/\s+/)) {
    const t = line ? line + " " + word : word;
    if (line && c.measureText(t).width > width) { out.push(line); line = word; } else line = t;
  }
  if (line) out.push(line);
  return out;
}

function closed(a) { return a.concat([a[0]]); }

function drawPlots() {
  const t = S.turn;
  if (!t) return;
  const phi = closed(t.phi_deg).map((x, i) => i === t.phi_deg.length ? 360 : x);
  const cur = t.phi_deg[S.k];
  const kind = +$("motion-kind").value, m = t.motion;
  const xt = [0, 90, 180, 270, 360];
  const series = [];
  // heights of the needle point and the take-up eye on the left axis (mm, m/s, m/s²), the
  // shuttle's angle on its own right-hand axis (deg, rad/s, rad/s²): two units, two axes
  const mm = [["y_mm", 1, "mm", "height"], ["vy_mm_s", 1e-3, "m/s", "velocity"],
              ["ay_mm_s2", 1e-3, "m/s²", "acceleration"]][kind];
  const ang = [["theta_deg", 1, "deg", "angle"], ["omega_rad_s", 1, "rad/s", "velocity"],
               ["epsilon_rad_s2", 1, "rad/s²", "accel."]][kind];
  const scaled = (a, f) => closed(a).map((v) => (v === null ? null : v * f));
  for (const key of ["needle_point", "take_up_eye"]) {
    if (m[key]) series.push({x: phi, y: scaled(m[key][mm[0]], mm[1]), label: m[key].label});
  }
  if (m.shuttle) {
    series.push({x: phi, y: scaled(m.shuttle[ang[0]], ang[1]), label: "shuttle (right axis)",
                 dash: [5, 3], axis: 1, color: COLORS[2]});
  }
  const left = series.some((x) => !x.axis);
  chart($("motion"), series, {xlabel: "shaft angle φ [deg]", cursor: cur, xrange: [0, 360], xticks: xt,
    ylabel: left ? `${mm[3]} [${mm[2]}]` : "", y2label: `shuttle ${ang[3]} [${ang[2]}]`,
    empty: "no needle, take-up or shuttle: this machine file has no [sewing] roles"});
  drawTiming(phi, cur);
  const f = t.feed;
  if (f && !f.error) {
    chart($("feed"), [{x: f.x_mm, y: f.y_mm, closed: true, label: `regulator ${fmt(f.regulator_deg, 1)}°: stitch ${fmt(f.stitch_mm, 2)} mm`}],
      {xlabel: "x [mm]", ylabel: "above the plate [mm]", equal: true,
       hlines: [{y: 0, color: "#000"}],
       markers: [{x: f.x_mm[Math.round(cur / 360 * f.x_mm.length) % f.x_mm.length],
                  y: f.y_mm[Math.round(cur / 360 * f.y_mm.length) % f.y_mm.length], color: "#d62728"}]});
  } else chart($("feed"), [], {empty: f && f.error ? f.error.what : "this machine has no feed dog"});
  const th = t.thread;
  if (th && !th.error) {
    const p = closed(th.phi_deg).map((x, i) => i === th.phi_deg.length ? 360 : x);
    chart($("thread"), [
      {x: p, y: closed(th.supply_mm), label: "take-up supply"},
      {x: p, y: closed(th.demand_mm), label: "demand"},
      {x: p, y: closed(th.overfeed_mm), label: "overfeed", dash: [4, 2]}],
    {xlabel: "shaft angle φ [deg]", ylabel: "thread [mm]", cursor: cur, xrange: [0, 360], xticks: xt,
     hlines: [{y: 0, color: "#888"}]});
  } else chart($("thread"), [], {empty: th && th.error ? th.error.what : "no [thread] in this machine file"});
  if (t.dynamics) {
    chart($("torque"), [{x: phi, y: scaled(t.dynamics.torque_Nmm, 1e-3), label: `at ${fmt(t.rpm, 0)} rpm [N m]`}],
      {xlabel: "shaft angle φ [deg]", ylabel: "torque [N m]", cursor: cur, xrange: [0, 360], xticks: xt, hlines: [{y: 0, color: "#888"}]});
    const F = t.dynamics.shaking_force_N;
    chart($("shaking"), [{x: F.map((v) => v[0]), y: F.map((v) => v[1]), closed: true, label: "shaking force [N]"}],
      {xlabel: "Fx [N]", ylabel: "Fy [N]", equal: true, markers: [{x: F[S.k][0], y: F[S.k][1], color: "#d62728"}, {x: 0, y: 0, color: "#888"}]});
  } else {
    chart($("torque"), [], {empty: S.machine.dynamics_note || "no dynamics"});
    chart($("shaking"), [], {empty: S.machine.dynamics_note || "no dynamics"});
  }
}

function spans(phi, mask) {  // [start, end] runs of a mask over phi (deg)
  const out = [];
  let a = null;
  for (let i = 0; i < mask.length; i++) {
    if (mask[i] && a === null) a = phi[i];
    if (!mask[i] && a !== null) { out.push([a, phi[i]]); a = null; }
  }
  if (a !== null) out.push([a, 360]);
  return out;
}

function drawTiming(phi, cur) {
  const t = S.turn, r = S.machine.roles, P = t.points;
  const rows = [];
  if (r.needle_point) {
    const y = closed(P[r.needle_point].y);
    rows.push({label: "needle in fabric", mask: y.map((v) => v !== null && v < r.plate_y + r.fabric_thickness), color: "#1f77b4"});
    rows.push({label: "needle below plate", mask: y.map((v) => v !== null && v < r.plate_y), color: "#aec7e8"});
  }
  if (r.feed_dog) {
    const y = closed(P[r.feed_dog].y);
    rows.push({label: "dog above plate", mask: y.map((v) => v !== null && v > r.plate_y), color: "#9467bd"});
  }
  if (t.motion.shuttle) {
    const th = closed(t.motion.shuttle.omega_rad_s);
    rows.push({label: "shuttle turning +", mask: th.map((v) => v !== null && v > 0), color: "#2ca02c"});
  }
  if (r.take_up_eye) {
    const v = closed(t.motion.take_up_eye.vy_mm_s);
    rows.push({label: "take-up eye rising", mask: v.map((x) => x !== null && x > 0), color: "#d62728"});
  }
  const [c, W, H] = ctxOf($("timing"));
  c.font = LABEL_FONT;
  if (!rows.length) {
    c.fillStyle = "#888";
    text(c, "no timing: this machine file has no [sewing] roles", 10, H / 2, {kind: "note"});
    return;
  }
  // the row labels' column as wide as the widest label; the angle axis in steps whose labels
  // do not run together (30 deg on a wide diagram, 60 or 90 on a narrow one)
  const L = 10 + Math.max(40, ...rows.map((row) => c.measureText(row.label).width));
  const R = 10, T = 4, B = 36, ph = H - T - B, rh = ph / Math.max(rows.length, 1);
  const X = (x) => L + x / 360 * (W - L - R);
  rows.forEach((row, i) => {
    c.fillStyle = "#333";
    text(c, row.label, L - 6, T + i * rh + rh / 2, {align: "right", baseline: "middle", kind: "row"});
    c.fillStyle = row.color;
    for (const [a, z] of spans(phi, row.mask)) c.fillRect(X(a), T + i * rh + 3, X(z) - X(a), rh - 6);
  });
  c.strokeStyle = "#999"; c.strokeRect(L, T, W - L - R, ph);
  c.font = FONT; c.fillStyle = "#555";
  const wide = c.measureText("360").width + 8;
  const step = [30, 45, 60, 90, 180].find((d) => (W - L - R) * d / 360 >= wide) || 360;
  for (let a = 0; a <= 360; a += step) {
    c.strokeStyle = "#999"; c.beginPath(); c.moveTo(X(a), T + ph); c.lineTo(X(a), T + ph + 3); c.stroke();
    text(c, String(a), X(a), T + ph + 4, {align: "center", baseline: "top", kind: "tick", optional: true});
  }
  c.font = LABEL_FONT; c.fillStyle = "#333";
  text(c, "shaft angle φ [deg]", L + (W - L - R) / 2, H - 3, {align: "center", baseline: "bottom", kind: "axis"});
  const ev = (S.checks && S.checks.events) || [];
  for (const e of ev) {
    if (e.unit !== "deg" || e.value === null || !/dead centre|meets/.test(e.event)) continue;
    c.strokeStyle = "#555"; c.setLineDash([3, 3]);
    c.beginPath(); c.moveTo(X(e.value), T); c.lineTo(X(e.value), T + ph); c.stroke(); c.setLineDash([]);
  }
  c.strokeStyle = "#000"; c.beginPath(); c.moveTo(X(cur), T); c.lineTo(X(cur), T + ph); c.stroke();
}

// where a point's label may go: a direction (dx, dy) and a distance, px; beside the point
// first, then farther out with a leader
const CANDIDATES = [];
for (const d of [5, 14, 26, 40]) {
  for (const [dx, dy] of [[1, -1], [1, 1], [-1, -1], [-1, 1], [1, 0], [-1, 0], [0, -1], [0, 1]]) {
    const f = dx && dy ? 0.7 : 1;
    CANDIDATES.push([dx * f, dy * f, d]);
  }
}

function viewOf(t) {  // the drawing's extent: every point over the turn
  let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
  for (const p of Object.values(t.points)) {
    for (let i = 0; i < p.x.length; i++) {
      if (p.x[i] === null) continue;
      x0 = Math.min(x0, p.x[i]); x1 = Math.max(x1, p.x[i]);
      y0 = Math.min(y0, p.y[i]); y1 = Math.max(y1, p.y[i]);
    }
  }
  return {x0, x1, y0, y1};
}

function drawFrame() {
  const t = S.turn;
  if (!t) return;
  const k = S.k, cv = $("mechanism");
  const v = viewOf(t);
  // keep the scale while the machine stays inside it, so that a change shows as motion
  if (!S.view || v.x0 < S.view.x0 || v.x1 > S.view.x1 || v.y0 < S.view.y0 || v.y1 > S.view.y1 ||
      (v.x1 - v.x0) < 0.5 * (S.view.x1 - S.view.x0) && (v.y1 - v.y0) < 0.5 * (S.view.y1 - S.view.y0)) {
    const m = 0.025 * Math.max(v.x1 - v.x0, v.y1 - v.y0, 1);
    S.view = {x0: v.x0 - m, x1: v.x1 + m, y0: v.y0 - m, y1: v.y1 + m};
  }
  const w = S.view;
  // the canvas takes the drawing's shape (a tall machine a tall canvas), as tall as the window
  // leaves room for beside the player and the numbers, and at least half as tall as wide
  const cw = cv.clientWidth || cv.width;
  const tallest = Math.max(0.5, (window.innerHeight - 160) / cw);
  const aspect = Math.min(Math.max((w.y1 - w.y0) / (w.x1 - w.x0), 0.5), tallest, 2.0);
  const [c, W, H] = ctxOf(cv, aspect);
  const s = Math.min(W / (w.x1 - w.x0), H / (w.y1 - w.y0));
  const ox = (W - s * (w.x1 - w.x0)) / 2, oy = (H - s * (w.y1 - w.y0)) / 2;
  const X = (x) => ox + (x - w.x0) * s, Y = (y) => H - oy - (y - w.y0) * s;
  cv.extent = {x0: X(v.x0), x1: X(v.x1), y0: Y(v.y1), y1: Y(v.y0)};  // the machine, px
  const P = t.points, r = S.machine.roles;
  const at = (n) => (P[n] && P[n].x[k] !== null ? [X(P[n].x[k]), Y(P[n].y[k])] : null);
  c.lineJoin = "round";
  // the throat plate
  if (r.plate_y !== undefined) {
    c.strokeStyle = "#888"; c.lineWidth = 1; c.setLineDash([6, 4]);
    c.beginPath(); c.moveTo(0, Y(r.plate_y)); c.lineTo(W, Y(r.plate_y)); c.stroke(); c.setLineDash([]);
    c.fillStyle = "#888"; c.font = FONT;
    text(c, "throat plate", 4, Y(r.plate_y) - 3, {kind: "plate"});
  }
  // paths over the turn: the thread eye, the dog, the needle point
  const paths = [[r.take_up_eye, "#d62728"], [r.feed_dog, "#9467bd"], [r.shuttle_point, "#2ca02c"]];
  for (const [n, col] of paths) {
    if (!n || !P[n]) continue;
    c.strokeStyle = col; c.lineWidth = 1; c.setLineDash([3, 2]);
    c.beginPath();
    P[n].x.forEach((x, i) => { if (x !== null) (i ? c.lineTo(X(x), Y(P[n].y[i])) : c.moveTo(X(x), Y(P[n].y[i]))); });
    c.closePath(); c.stroke(); c.setLineDash([]);
  }
  // links: every pair of their points, lightly filled
  let j = 0;
  for (const [link, pts] of Object.entries(S.machine.links)) {
    const xy = pts.map(at).filter((q) => q);
    const col = COLORS[j++ % COLORS.length];
    c.strokeStyle = col; c.lineWidth = 3; c.fillStyle = col + "22";
    if (xy.length === 1) { c.beginPath(); c.arc(xy[0][0], xy[0][1], 6, 0, 2 * Math.PI); c.stroke(); continue; }
    if (xy.length >= 3) {
      c.beginPath(); xy.forEach(([x, y], i) => (i ? c.lineTo(x, y) : c.moveTo(x, y))); c.closePath(); c.fill();
    }
    c.beginPath();
    const first = xy.length <= 4 ? xy.length : 1;
    for (let a = 0; a < first; a++) for (let b = a + 1; b < xy.length; b++) {
      c.moveTo(xy[a][0], xy[a][1]); c.lineTo(xy[b][0], xy[b][1]);
    }
    c.stroke();
  }
  // sliders: a block on its guide's direction
  (t.sliders || []).forEach((sl, i) => {
    const info = S.machine.sliders[i], q = info && at(info.point);
    const a = sl.angle_deg[k];
    if (!q || a === null) return;
    c.save(); c.translate(q[0], q[1]); c.rotate(-a * Math.PI / 180);
    c.strokeStyle = "#333"; c.lineWidth = 1; c.setLineDash([2, 3]);
    c.beginPath(); c.moveTo(-40, 0); c.lineTo(40, 0); c.stroke(); c.setLineDash([]);
    c.fillStyle = "#ffd54f"; c.lineWidth = 1.5; c.fillRect(-9, -5, 18, 10); c.strokeRect(-9, -5, 18, 10);
    c.restore();
  });
  // frame pivots and points
  for (const n of S.machine.frame_points) {
    const q = at(n); if (!q) continue;
    c.fillStyle = "#555"; c.beginPath(); c.moveTo(q[0], q[1]); c.lineTo(q[0] - 6, q[1] + 10); c.lineTo(q[0] + 6, q[1] + 10); c.closePath(); c.fill();
  }
  for (const n of S.machine.points) {
    const q = at(n); if (!q) continue;
    c.fillStyle = "#fff"; c.strokeStyle = "#222"; c.lineWidth = 1.2;
    c.beginPath(); c.arc(q[0], q[1], 2.8, 0, 2 * Math.PI); c.fill(); c.stroke();
  }
  // the roles' labels, each beside its point where it touches no other label and stays inside
  // the canvas (covering as few points as it can); a label keeps its place while it may
  c.font = LABEL_FONT;
  const dots = S.machine.points.map(at).filter((q) => q);
  S.labelPlaces = S.labelPlaces || {};
  for (const [n, lab] of [[r.needle_point, "needle"], [r.take_up_eye, "take-up eye"], [r.feed_dog, "feed dog"], [r.shuttle_point, "shuttle point"]]) {
    const q = n && at(n);
    if (!q) continue;
    const box0 = textBox(c, lab, 0, 0, "left", "middle");
    const bw = box0.x1 - box0.x0, bh = box0.y1 - box0.y0;
    let best = null;
    CANDIDATES.forEach(([dx, dy, d], i) => {
      const cx = q[0] + dx * d + Math.sign(dx) * bw / 2, cy = q[1] + dy * d + Math.sign(dy) * bh / 2;
      const box = {x0: cx - bw / 2, x1: cx + bw / 2, y0: cy - bh / 2, y1: cy + bh / 2};
      if (box.x0 < 2 || box.x1 > W - 2 || box.y0 < 2 || box.y1 > H - 2) return;
      if (cv.labels.some((b) => overlaps(box, b, 2))) return;
      const covered = dots.filter(([x, y]) => x > box.x0 - 3 && x < box.x1 + 3 && y > box.y0 - 3 && y < box.y1 + 3).length;
      const score = (i === S.labelPlaces[lab] ? -0.5 : 0) + covered * 4 + i / CANDIDATES.length + d / 10;
      if (!best || score < best.score) best = {score, box, i, d};
    });
    if (!best) continue;  // (no room at all: a canvas too small to label)
    S.labelPlaces[lab] = best.i;
    const b = best.box;
    if (best.d > 8) {  // a leader from the point to the label
      c.strokeStyle = "#666"; c.lineWidth = 0.8;
      c.beginPath(); c.moveTo(q[0], q[1]);
      c.lineTo(Math.min(Math.max(q[0], b.x0), b.x1), Math.min(Math.max(q[1], b.y0), b.y1)); c.stroke();
    }
    c.fillStyle = "#222";
    text(c, lab, b.x0, (b.y0 + b.y1) / 2, {baseline: "middle", kind: "point", halo: true});
  }
  $("scrub").max = t.phi_deg.length - 1; $("scrub").value = k;
  $("phi").textContent = `φ = ${fmt(t.phi_deg[k], 0)}°`;
}

let last = 0;
function tick(now) {
  if (S.playing && S.turn && now - last > 33) {  // a turn in 6 s (180 positions, 30 per s)
    last = now;
    S.k = (S.k + 1) % S.turn.phi_deg.length;
    drawFrame();
    if (S.k % 3 === 0) drawPlots();
  }
  requestAnimationFrame(tick);
}

init().catch(showError);
