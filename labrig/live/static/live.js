// labrig live page: polls the run's JSON endpoints and draws p-v and l-v in SVG.
// Read-only: it only ever sends GET requests. No library, no CDN: it works offline.
"use strict";

const POLL_MS = 400; // at least twice a second
const SVG = "http://www.w3.org/2000/svg";
const MARGIN = { left: 58, right: 16, top: 14, bottom: 44 };
const WIDTH = 640, HEIGHT = 420;

const live = {
  info: null,
  model: null,
  pressure: [], // [repetition, t_s, v_ml, p_kpa]
  length: [], // [repetition, t_s, v_ml, l_mm]
  nextPressure: 0,
  nextLength: 0,
  transitions: [],
  state: null,
  remaining_s: null,
  reason: "",
  detectionError: "",
};
window.labrigLive = live; // for tests and for a curious technician's console

async function getJSON(path) {
  const response = await fetch(path, { cache: "no-store" });
  if (!response.ok) throw new Error(`${path}: HTTP ${response.status}`);
  return response.json();
}

function text(id, value) {
  document.getElementById(id).textContent = value;
}

function fmt(x, digits, unit) {
  return x === null || x === undefined ? "-" : `${x.toFixed(digits)} ${unit}`;
}

function minutes(s) {
  if (s === null || s === undefined) return "-";
  const m = Math.floor(s / 60);
  return `${m}:${String(Math.round(s - 60 * m)).padStart(2, "0")} min`;
}

function showState() {
  const s = live.state;
  if (!s) return;
  const status = document.getElementById("status");
  status.textContent = s.status;
  status.className = `status ${s.status}`;
  text("step", s.step);
  text("repetition", s.repetition ? `${s.repetition} / ${s.repetitions}` : `- / ${s.repetitions}`);
  text("left", minutes(live.remaining_s));
  text("volume", fmt(s.volume_ml, 2, "mL"));
  text("pressure", fmt(s.pressure_kpa, 1, "kPa"));
  text("length", fmt(s.length_mm, 1, "mm"));
  const banner = document.getElementById("banner");
  const stopped = s.status === "aborted" || s.status === "faulted";
  banner.hidden = !stopped;
  if (stopped) banner.textContent = `${s.status}: ${live.reason || "the run stopped"}`;
}

// ---- plotting --------------------------------------------------------------------

function niceTicks(lo, hi, count) {
  const span = hi - lo || 1;
  const raw = span / count;
  const power = Math.pow(10, Math.floor(Math.log10(raw)));
  const step = [1, 2, 5, 10].map((k) => k * power).find((s) => span / s <= count) || 10 * power;
  const ticks = [];
  for (let t = Math.ceil(lo / step) * step; t <= hi + 1e-9 * span; t += step) ticks.push(+t.toFixed(10));
  return ticks;
}

function extent(values, fallback) {
  let lo = Infinity, hi = -Infinity;
  for (const v of values) if (v !== null && isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  if (lo === Infinity) return fallback;
  if (hi - lo < 1e-9) { lo -= 1; hi += 1; }
  const pad = 0.05 * (hi - lo);
  return [lo - pad, hi + pad];
}

function node(name, attrs, parent) {
  const el = document.createElementNS(SVG, name);
  for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, v);
  if (parent) parent.appendChild(el);
  return el;
}

function drawPlot(svgId, points, modelY, markerY, yLabel) {
  const svg = document.getElementById(svgId);
  while (svg.firstChild) svg.removeChild(svg.firstChild);
  const model = live.model && live.model.v_ml ? live.model : null;
  let vMax = live.info ? live.info.max_volume_ml : 1;
  for (const p of points) vMax = Math.max(vMax, p[2]);
  const xRange = [0, vMax * 1.04 || 1];
  const ys = points.map((p) => p[3]).concat(model ? model[modelY] : []);
  const yRange = extent(ys, [0, 1]);
  const x = (v) => MARGIN.left + ((v - xRange[0]) / (xRange[1] - xRange[0])) * (WIDTH - MARGIN.left - MARGIN.right);
  const y = (v) => HEIGHT - MARGIN.bottom - ((v - yRange[0]) / (yRange[1] - yRange[0])) * (HEIGHT - MARGIN.top - MARGIN.bottom);

  const grid = node("g", { class: "grid" }, svg);
  const axis = node("g", { class: "axis" }, svg);
  for (const t of niceTicks(xRange[0], xRange[1], 8)) {
    node("line", { x1: x(t), x2: x(t), y1: MARGIN.top, y2: HEIGHT - MARGIN.bottom }, grid);
    node("text", { x: x(t), y: HEIGHT - MARGIN.bottom + 16, "text-anchor": "middle" }, axis).textContent = t;
  }
  for (const t of niceTicks(yRange[0], yRange[1], 6)) {
    node("line", { x1: MARGIN.left, x2: WIDTH - MARGIN.right, y1: y(t), y2: y(t) }, grid);
    node("text", { x: MARGIN.left - 6, y: y(t) + 4, "text-anchor": "end" }, axis).textContent = t;
  }
  node("path", { d: `M${MARGIN.left},${MARGIN.top}V${HEIGHT - MARGIN.bottom}H${WIDTH - MARGIN.right}`, fill: "none" }, axis);
  node("text", { x: (MARGIN.left + WIDTH - MARGIN.right) / 2, y: HEIGHT - 8, "text-anchor": "middle" }, axis).textContent = "supplied volume (mL)";
  node("text", { x: 14, y: (MARGIN.top + HEIGHT - MARGIN.bottom) / 2, "text-anchor": "middle", transform: `rotate(-90 14 ${(MARGIN.top + HEIGHT - MARGIN.bottom) / 2})` }, axis).textContent = yLabel;

  // the model: its path dashed (a snap is two points at one volume: a dashed jump),
  // and each predicted transition as a dashed vertical line
  let modelPoints = 0;
  if (model) {
    for (const direction of [1, -1]) {
      const pts = [];
      model.v_ml.forEach((v, i) => {
        if (model.direction[i] === direction && model[modelY][i] !== null) pts.push(`${x(v).toFixed(1)},${y(model[modelY][i]).toFixed(1)}`);
      });
      if (pts.length) node("polyline", { class: "model", "data-direction": direction, points: pts.join(" ") }, svg);
      modelPoints += pts.length;
    }
    for (const t of model.transitions) {
      node("line", { class: "model-transition", x1: x(t.v_ml), x2: x(t.v_ml), y1: MARGIN.top, y2: HEIGHT - MARGIN.bottom }, svg);
    }
  }

  // the measurement over the model: earlier repetitions grey, the current one in
  // colour, on top
  let newest = 0;
  for (const p of points) newest = Math.max(newest, p[0]);
  const current = live.state && live.state.repetition ? live.state.repetition : newest;
  const byRep = new Map();
  for (const p of points) {
    if (!byRep.has(p[0])) byRep.set(p[0], []);
    byRep.get(p[0]).push(`${x(p[2]).toFixed(1)},${y(p[3]).toFixed(1)}`);
  }
  const reps = [...byRep.keys()].sort((a, b) => (a === current) - (b === current) || a - b);
  for (const rep of reps) {
    node("polyline", { class: rep === current ? "current" : "earlier", "data-repetition": rep, points: byRep.get(rep).join(" ") }, svg);
  }

  // each transition detected so far, where it was measured
  let markers = 0, labelled = 0;
  for (const t of live.transitions) {
    if (t[markerY] === null) continue;
    const cx = x(t.v_ml), cy = y(t[markerY]);
    const now = t.repetition === current;
    node("circle", { class: now ? "measured-transition" : "measured-transition earlier-transition", cx, cy, r: now ? 5.5 : 3.5, "data-repetition": t.repetition }, svg);
    markers += 1;
    if (!now) continue; // the current repetition's are labelled, alternately above and below
    const way = t.direction === "inflate" ? "+" : "\u2212";
    const dy = labelled++ % 2 ? 18 : -8;
    node("text", { class: "measured-label", x: cx + 8, y: cy + dy }, svg).textContent = `${way}${t.v_ml.toFixed(1)} mL`;
  }
  svg.dataset.points = points.length;
  svg.dataset.modelPoints = modelPoints;
  svg.dataset.transitions = markers;
}

function draw() {
  showState();
  drawPlot("pv", live.pressure, "p_kpa", "p_kpa", "pressure (kPa)");
  drawPlot("lv", live.length, "l_mm", "l_mm", "length (mm)");
}

// ---- polling ---------------------------------------------------------------------

let busy = false;
async function poll() {
  if (busy) return; // a slow answer delays the next poll; requests never pile up
  busy = true;
  try {
    const [state, series] = await Promise.all([
      getJSON("/api/state"),
      getJSON(`/api/series?pressure=${live.nextPressure}&length=${live.nextLength}`),
    ]);
    live.state = state;
    live.pressure.push(...series.pressure);
    live.length.push(...series.length);
    live.nextPressure = series.next_pressure;
    live.nextLength = series.next_length;
    live.transitions = series.transitions;
    live.remaining_s = series.remaining_s;
    live.reason = series.reason;
    live.detectionError = series.detection_error;
    if (live.model === null || !live.model.ready) live.model = await getJSON("/api/model");
  } catch (error) {
    const status = document.getElementById("status");
    status.textContent = "no connection";
    status.className = "status";
    busy = false;
    return;
  }
  const model = live.model.error ? `model: ${live.model.error}` : live.model.ready ? "" : "model: computing...";
  const detection = live.detectionError ? `transition detection: ${live.detectionError}` : "";
  text("model-note", [model, detection].filter(Boolean).join("; "));
  try {
    draw();
  } finally {
    busy = false; // a drawing error shows in the console, and the next poll draws again
  }
}

async function main() {
  live.info = await getJSON("/api/info");
  document.title = `labrig live: ${live.info.title}`;
  text("title", `${live.info.title} (${live.info.segments.join(" + ")})`);
  await poll();
  setInterval(poll, POLL_MS);
}

main().catch(() => text("status", "no connection"));
