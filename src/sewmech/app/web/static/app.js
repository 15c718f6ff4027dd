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

async function download(what) {
  try {
    const r = await fetch(`/api/sessions/${S.token}/${what}`, {
      method: "POST", headers: {"Content-Type": "application/json"},
      body: JSON.stringify({set: S.turnValues || {}})});
    if (!r.ok) throw Object.assign(new Error("export"), {info: (await r.json()).error});
    const blob = await r.blob();
    const name = (r.headers.get("content-disposition") || "").match(/filename="([^"]+)"/);
    const a = document.createElement("a");
    a.href = URL.createObjectURL(blob);
    a.download = name ? name[1] : what;
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
  } else {
    $("torque-max").textContent = $("shake-max").textContent = "– (no masses)";
  }
}

function renderChecks() {
  const body = $("checks").tBodies[0];
  body.replaceChildren();
  const rows = [...((S.checks && S.checks.checks) || []), ...((S.turn && S.turn.thread && S.turn.thread.checks) || [])];
  for (const c of rows) {
    const tr = body.insertRow();
    tr.insertCell().textContent = c.check;
    const v = tr.insertCell(); v.className = "num"; v.textContent = `${fmt(c.value, 3)} ${c.unit}`;
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

function ctxOf(canvas) {
  const dpr = window.devicePixelRatio || 1;
  const w = canvas.clientWidth || canvas.width, h = Math.round(w * canvas.height / canvas.width);
  if (canvas._w !== w || canvas._dpr !== dpr) {
    canvas._w = w; canvas._dpr = dpr; canvas._h = h;
    canvas.width = Math.round(w * dpr); canvas.height = Math.round(h * dpr);
    canvas.style.height = h + "px";
  }
  const c = canvas.getContext("2d");
  c.setTransform(dpr, 0, 0, dpr, 0, 0);
  c.clearRect(0, 0, canvas._w, canvas._h);
  return [c, canvas._w, canvas._h];
}

function niceTicks(lo, hi, n = 5) {
  if (!(hi > lo)) { hi = lo + 1; lo -= 1; }
  const step0 = (hi - lo) / n, mag = Math.pow(10, Math.floor(Math.log10(step0)));
  const step = [1, 2, 2.5, 5, 10].map((m) => m * mag).find((s) => s >= step0);
  const out = [];
  for (let v = Math.ceil(lo / step) * step; v <= hi + 1e-9 * step; v += step) out.push(+v.toFixed(10));
  return out;
}

// a line chart: series [{x, y, color, label, dash}], options {xlabel, ylabel, cursor, equal, bands, hlines, xticks}
function chart(canvas, series, o = {}) {
  const [c, W, H] = ctxOf(canvas);
  const L = 52, R = 8, T = 8, B = 30;
  let xs = [], ys = [];
  for (const s of series) for (let i = 0; i < s.x.length; i++) {
    if (s.x[i] !== null && s.y[i] !== null) { xs.push(s.x[i]); ys.push(s.y[i]); }
  }
  for (const h of o.hlines || []) ys.push(h.y);
  if (!xs.length) { c.fillStyle = "#888"; c.fillText(o.empty || "nothing to show", L, H / 2); return; }
  let x0 = o.xrange ? o.xrange[0] : Math.min(...xs), x1 = o.xrange ? o.xrange[1] : Math.max(...xs);
  let y0 = Math.min(...ys), y1 = Math.max(...ys);
  const py = (y1 - y0) * 0.06 || 1; y0 -= py; y1 += py;
  if (!o.xrange) { const px = (x1 - x0) * 0.04 || 1; x0 -= px; x1 += px; }
  const pw = W - L - R, ph = H - T - B;
  if (o.equal) {  // the same mm per pixel on both axes
    const sx = (x1 - x0) / pw, sy = (y1 - y0) / ph, s = Math.max(sx, sy);
    const cx = (x0 + x1) / 2, cy = (y0 + y1) / 2;
    x0 = cx - s * pw / 2; x1 = cx + s * pw / 2; y0 = cy - s * ph / 2; y1 = cy + s * ph / 2;
  }
  const X = (x) => L + (x - x0) / (x1 - x0) * pw, Y = (y) => T + (y1 - y) / (y1 - y0) * ph;
  c.font = "10px system-ui, sans-serif"; c.lineWidth = 1;
  for (const b of o.bands || []) {
    c.fillStyle = b.color;
    for (const [a, z] of b.spans) c.fillRect(X(a), T, X(z) - X(a), ph);
  }
  c.strokeStyle = "#e3e3e3"; c.fillStyle = "#555"; c.textAlign = "center";
  for (const t of o.xticks || niceTicks(x0, x1)) {
    if (t < x0 || t > x1) continue;
    c.beginPath(); c.moveTo(X(t), T); c.lineTo(X(t), T + ph); c.stroke();
    c.fillText(fmt(t, 2), X(t), T + ph + 12);
  }
  c.textAlign = "right";
  for (const t of niceTicks(y0, y1)) {
    if (t < y0 || t > y1) continue;
    c.beginPath(); c.moveTo(L, Y(t)); c.lineTo(L + pw, Y(t)); c.stroke();
    c.fillText(fmt(t, 3), L - 4, Y(t) + 3);
  }
  c.strokeStyle = "#999"; c.strokeRect(L, T, pw, ph);
  c.textAlign = "center"; c.fillText(o.xlabel || "", L + pw / 2, H - 4);
  c.save(); c.translate(11, T + ph / 2); c.rotate(-Math.PI / 2); c.fillText(o.ylabel || "", 0, 0); c.restore();
  for (const h of o.hlines || []) {
    c.strokeStyle = h.color || "#000"; c.setLineDash(h.dash || []);
    c.beginPath(); c.moveTo(L, Y(h.y)); c.lineTo(L + pw, Y(h.y)); c.stroke(); c.setLineDash([]);
  }
  c.save(); c.beginPath(); c.rect(L, T, pw, ph); c.clip();
  series.forEach((s, j) => {
    c.strokeStyle = s.color || COLORS[j % COLORS.length]; c.lineWidth = s.width || 1.5;
    c.setLineDash(s.dash || []);
    c.beginPath();
    let up = false;
    for (let i = 0; i < s.x.length; i++) {
      if (s.x[i] === null || s.y[i] === null) { up = false; continue; }
      if (up) c.lineTo(X(s.x[i]), Y(s.y[i])); else { c.moveTo(X(s.x[i]), Y(s.y[i])); up = true; }
    }
    if (s.closed && s.x.length) c.lineTo(X(s.x[0]), Y(s.y[0]));
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
  // legend
  let lx = L + 6;
  c.textAlign = "left";
  series.forEach((s, j) => {
    if (!s.label) return;
    c.fillStyle = s.color || COLORS[j % COLORS.length];
    c.fillRect(lx, T + 5, 10, 3); c.fillStyle = "#333"; c.fillText(s.label, lx + 13, T + 10);
    lx += c.measureText(s.label).width + 24;
  });
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
  const label = ["position", "velocity", "acceleration"][kind];
  const mm = [["y_mm", 1, "mm"], ["vy_mm_s", 1e-3, "m/s"], ["ay_mm_s2", 1e-3, "m/s²"]][kind];
  const ang = [["theta_deg", 1, "deg"], ["omega_rad_s", 1, "rad/s"], ["epsilon_rad_s2", 1, "rad/s²"]][kind];
  const scaled = (a, f) => closed(a).map((v) => (v === null ? null : v * f));
  for (const key of ["needle_point", "take_up_eye"]) {
    if (m[key]) series.push({x: phi, y: scaled(m[key][mm[0]], mm[1]), label: `${m[key].label} [${mm[2]}]`});
  }
  if (m.shuttle) {
    // the shuttle in its own unit on the same chart would hide the others: scale to fit, say so
    const ys = scaled(m.shuttle[ang[0]], ang[1]);
    series.push({x: phi, y: ys, label: `shuttle [${ang[2]}]`, dash: [5, 3]});
  }
  chart($("motion"), series, {xlabel: "shaft angle φ [deg]", ylabel: label, cursor: cur, xrange: [0, 360], xticks: xt});
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
    {xlabel: "shaft angle φ [deg]", ylabel: "mm", cursor: cur, xrange: [0, 360], xticks: xt,
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
  const L = 120, R = 8, T = 4, B = 22, ph = H - T - B, rh = ph / Math.max(rows.length, 1);
  const X = (x) => L + x / 360 * (W - L - R);
  c.font = "11px system-ui, sans-serif";
  rows.forEach((row, i) => {
    c.fillStyle = "#333"; c.textAlign = "right"; c.fillText(row.label, L - 6, T + i * rh + rh / 2 + 4);
    c.fillStyle = row.color;
    for (const [a, z] of spans(phi, row.mask)) c.fillRect(X(a), T + i * rh + 3, X(z) - X(a), rh - 6);
  });
  c.strokeStyle = "#999"; c.strokeRect(L, T, W - L - R, ph);
  c.fillStyle = "#555"; c.textAlign = "center";
  for (let a = 0; a <= 360; a += 30) { c.fillText(a, X(a), H - 8); }
  const ev = (S.checks && S.checks.events) || [];
  for (const e of ev) {
    if (e.unit !== "deg" || e.value === null || !/dead centre|meets/.test(e.event)) continue;
    c.strokeStyle = "#555"; c.setLineDash([3, 3]);
    c.beginPath(); c.moveTo(X(e.value), T); c.lineTo(X(e.value), T + ph); c.stroke(); c.setLineDash([]);
  }
  c.strokeStyle = "#000"; c.beginPath(); c.moveTo(X(cur), T); c.lineTo(X(cur), T + ph); c.stroke();
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
  const [c, W, H] = ctxOf(cv);
  const v = viewOf(t);
  // keep the scale while the machine stays inside it, so that a change shows as motion
  if (!S.view || v.x0 < S.view.x0 || v.x1 > S.view.x1 || v.y0 < S.view.y0 || v.y1 > S.view.y1 ||
      (v.x1 - v.x0) < 0.5 * (S.view.x1 - S.view.x0) && (v.y1 - v.y0) < 0.5 * (S.view.y1 - S.view.y0)) {
    const m = 0.06 * Math.max(v.x1 - v.x0, v.y1 - v.y0, 1);
    S.view = {x0: v.x0 - m, x1: v.x1 + m, y0: v.y0 - m, y1: v.y1 + m};
  }
  const w = S.view, s = Math.min(W / (w.x1 - w.x0), H / (w.y1 - w.y0));
  const ox = (W - s * (w.x1 - w.x0)) / 2, oy = (H - s * (w.y1 - w.y0)) / 2;
  const X = (x) => ox + (x - w.x0) * s, Y = (y) => H - oy - (y - w.y0) * s;
  const P = t.points, r = S.machine.roles;
  const at = (n) => (P[n] && P[n].x[k] !== null ? [X(P[n].x[k]), Y(P[n].y[k])] : null);
  c.lineJoin = "round";
  // the throat plate
  if (r.plate_y !== undefined) {
    c.strokeStyle = "#888"; c.lineWidth = 1; c.setLineDash([6, 4]);
    c.beginPath(); c.moveTo(0, Y(r.plate_y)); c.lineTo(W, Y(r.plate_y)); c.stroke(); c.setLineDash([]);
    c.fillStyle = "#888"; c.font = "10px system-ui"; c.fillText("throat plate", 4, Y(r.plate_y) - 3);
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
  c.fillStyle = "#222"; c.font = "11px system-ui";
  for (const [n, lab] of [[r.needle_point, "needle"], [r.take_up_eye, "take-up eye"], [r.feed_dog, "feed dog"], [r.shuttle_point, "shuttle point"]]) {
    const q = n && at(n); if (q) c.fillText(lab, q[0] + 6, q[1] - 6);
  }
  c.fillText(`${S.machine.name}   φ = ${fmt(t.phi_deg[k], 0)}°`, 6, 14);
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
