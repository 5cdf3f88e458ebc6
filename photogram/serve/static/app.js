/* photogram measure --serve: the measuring page.
 *
 * Plain JavaScript, no build step, nothing from the network: every request
 * goes to the server that served this page (127.0.0.1), with the token of
 * the page's URL in the X-Photogram-Token header (images: ?token=).
 * Coordinates are image pixels, the top-left corner of the image at (0, 0):
 * each view is an <svg> whose viewBox is in image pixels, so overlays are
 * drawn (and read by tests) in image coordinates. docs/measure-serve.md.
 */
"use strict";

const SVGNS = "http://www.w3.org/2000/svg";
const TOKEN = new URLSearchParams(location.search).get("token") || "";
const PICK_PX = 8;        // a click within this many screen px selects an observation
const DRAG_PX = 3;        // a press that moves further is a drag, not a click

// the state tests read (tests/test_serve_browser.py)
const state = {
  ready: false, selected: null, lastRefine: null, pending: 0, error: null,
  project: null, epipolar: null, lastSave: null, lastRun: null, predictedLines: [],
};
window.photogramState = state;

const ui = {};            // elements by id
const views = new Map();  // view id -> {info, svg, vb:{x,y,w,h}, groups}
let exposure = null;      // the exposure shown (video projects)
let epiSource = null;     // what the epipolar lines belong to: {oid} or {view,x,y}
let predLabel = null;     // label whose predicted positions are drawn
let spaceDown = false;

// ---------------------------------------------------------------- requests

async function api(method, path, body) {
  state.pending += 1;
  try {
    const opts = {method, headers: {"X-Photogram-Token": TOKEN}};
    if (body !== undefined) {
      opts.headers["Content-Type"] = "application/json";
      opts.body = JSON.stringify(body);
    }
    const resp = await fetch(path, opts);
    let data = null;
    try { data = await resp.json(); } catch (e) { data = null; }
    if (!resp.ok) {
      const msg = (data && data.error) || `${method} ${path}: HTTP ${resp.status}`;
      const err = new Error(msg);
      err.status = resp.status;
      throw err;
    }
    return data;
  } finally {
    state.pending -= 1;
  }
}

function query(params) {
  return Object.entries(params)
    .map(([k, v]) => `${encodeURIComponent(k)}=${encodeURIComponent(v)}`).join("&");
}

function setStatus(text, isError) {
  ui.status.textContent = text;
  ui.status.classList.toggle("error", !!isError);
  state.error = isError ? text : null;
}

function fail(err) {
  setStatus(String(err && err.message ? err.message : err), true);
}

// ---------------------------------------------------------------- helpers

function el(name, attrs, parent) {
  const node = document.createElementNS(SVGNS, name);
  for (const [k, v] of Object.entries(attrs || {})) node.setAttribute(k, v);
  if (parent) parent.appendChild(node);
  return node;
}

function clear(node) { while (node.firstChild) node.removeChild(node.firstChild); }

function fmt(v, digits) { return Number(v).toFixed(digits); }

/** Image coordinates of a mouse event on a view's svg. */
function toImage(v, evt) {
  const p = v.svg.createSVGPoint();
  p.x = evt.clientX; p.y = evt.clientY;
  const q = p.matrixTransform(v.svg.getScreenCTM().inverse());
  return {x: q.x, y: q.y};
}

/** Image px per screen px of a view (overlay sizes stay constant on screen). */
function imagePerScreen(v) {
  const m = v.svg.getScreenCTM();
  return m && m.a ? 1 / m.a : 1;
}

function shownViews() {
  const all = state.project ? state.project.views : [];
  return all.filter((v) => exposure === null || v.exposure === exposure);
}

/** A point of a line (ski edge) in the form of an observation: point = its line label. */
function linePoint(p) { return {...p, point: p.line, isLine: true}; }

/** The observation (or line point) with this oid, or null. */
function observation(oid) {
  if (!state.project || oid === null) return null;
  const o = state.project.observations.find((q) => q.oid === oid);
  if (o) return o;
  const p = (state.project.lines || []).find((q) => q.oid === oid);
  return p ? linePoint(p) : null;
}

/** The line labels of the project (the ski lines measured somewhere). */
function lineLabels() {
  return new Set((state.project.lines || []).map((p) => p.line));
}

// ---------------------------------------------------------------- building the views

function buildViews() {
  clear(ui.views);
  views.clear();
  for (const info of shownViews()) {
    const fig = document.createElement("figure");
    fig.className = "view-box";
    const cap = document.createElement("figcaption");
    const name = document.createElement("span");
    name.className = "name";
    name.textContent = info.id;
    const size = document.createElement("span");
    size.textContent = `${info.width} \u00d7 ${info.height} px`;
    const fit = document.createElement("button");
    fit.type = "button"; fit.className = "fit"; fit.textContent = "fit";
    cap.append(name, size, fit);
    fig.appendChild(cap);
    if (!info.ok) {
      const p = document.createElement("p");
      p.className = "view-error";
      p.textContent = info.error || `cannot read the image of ${info.id}`;
      fig.appendChild(p);
    }
    const w = info.width || 640, h = info.height || 480;
    const svg = el("svg", {class: "view", "data-view": info.id, viewBox: `0 0 ${w} ${h}`,
                           preserveAspectRatio: "xMidYMid meet"});
    svg.style.aspectRatio = `${w} / ${h}`;
    if (info.ok) {
      el("image", {href: `/api/image?${query({view: info.id, token: TOKEN})}`, x: 0, y: 0,
                   width: w, height: h, preserveAspectRatio: "none"}, svg);
    } else {
      el("rect", {class: "missing", x: 0, y: 0, width: w, height: h}, svg);
    }
    const groups = {};
    for (const g of ["lines", "res", "obs", "epi", "pred"]) groups[g] = el("g", {class: g}, svg);
    fig.appendChild(svg);
    ui.views.appendChild(fig);
    const v = {info, svg, vb: {x: 0, y: 0, w, h}, groups};
    views.set(info.id, v);
    fit.addEventListener("click", () => { setViewBox(v, {x: 0, y: 0, w, h}); });
    attachMouse(v);
  }
}

function setViewBox(v, vb) {
  v.vb = vb;
  v.svg.setAttribute("viewBox", `${vb.x} ${vb.y} ${vb.w} ${vb.h}`);
  drawView(v);
}

/** Show an image position in the middle of its view, zoomed to `width` image px. */
function zoomTo(v, x, y, width) {
  const w = Math.min(width, v.info.width || width);
  const h = w * (v.vb.h / v.vb.w);
  setViewBox(v, {x: x - w / 2, y: y - h / 2, w, h});
}

// ---------------------------------------------------------------- drawing

function drawAll() {
  for (const v of views.values()) drawView(v);
}

function drawView(v) {
  const k = imagePerScreen(v);
  drawObservations(v, k);
  drawResiduals(v);
  drawLines(v, k);
  drawEpipolar(v, k);
}

function drawObservations(v, k) {
  const g = v.groups.obs;
  clear(g);
  const arm = 7 * k, font = 12 * k;
  for (const o of state.project.observations) {
    if (o.view !== v.info.id) continue;
    const cls = ["ob"];
    if (o.manual) cls.push("manual");
    if (o.oid === state.selected) cls.push("selected");
    const og = el("g", {class: cls.join(" "), "data-oid": o.oid, "data-point": o.point}, g);
    el("line", {x1: o.x - arm, y1: o.y, x2: o.x + arm, y2: o.y}, og);
    el("line", {x1: o.x, y1: o.y - arm, x2: o.x, y2: o.y + arm}, og);
    if (o.oid === state.selected) el("circle", {class: "ring", cx: o.x, cy: o.y, r: 1.6 * arm}, og);
    const t = el("text", {x: o.x + arm * 0.8, y: o.y - arm * 0.8, "font-size": font}, og);
    t.textContent = o.point;
  }
}

function drawResiduals(v) {
  const g = v.groups.res;
  clear(g);
  const scale = Number(ui.resScale.value) || 0;
  if (!scale) return;
  const at = new Map();
  for (const o of state.project.observations) if (o.view === v.info.id) at.set(o.point, o);
  for (const r of state.project.residuals) {
    if (r.view !== v.info.id) continue;
    const o = (r.oid !== null && r.oid !== undefined) ? observation(r.oid) : at.get(r.point);
    if (!o) continue;
    el("line", {class: "res", "data-point": r.point, x1: o.x, y1: o.y,
                x2: o.x + scale * r.vx, y2: o.y + scale * r.vy}, g);
  }
}

function drawLines(v, k) {
  const g = v.groups.lines;
  clear(g);
  const byLabel = new Map();
  for (const p of state.project.lines || []) {
    if (p.view !== v.info.id) continue;
    if (!byLabel.has(p.line)) byLabel.set(p.line, []);
    byLabel.get(p.line).push(p);
  }
  for (const [label, pts] of byLabel) {
    el("polyline", {"data-line": label, points: pts.map((p) => `${p.x},${p.y}`).join(" ")}, g);
    for (const p of pts) {
      const sel = p.oid === state.selected;
      el("circle", {cx: p.x, cy: p.y, r: (sel ? 4 : 2) * k, "data-oid": p.oid,
                    class: sel ? "selected" : ""}, g);
    }
    const t = el("text", {x: pts[0].x + 4 * k, y: pts[0].y - 4 * k, "font-size": 12 * k}, g);
    t.textContent = label;
  }
}

function drawEpipolar(v, k) {
  const ge = v.groups.epi, gp = v.groups.pred;
  clear(ge); clear(gp);
  const epi = state.epipolar;
  if (epi) {
    for (const line of epi.lines || []) {
      if (line.view !== v.info.id) continue;
      el("polyline", {class: "epi", "data-view": line.view,
                      points: line.points.map((p) => `${p[0]},${p[1]}`).join(" ")}, ge);
    }
    for (const p of epi.predicted || []) {
      if (p.view !== v.info.id) continue;
      el("circle", {class: "pred", "data-view": p.view, cx: p.x, cy: p.y, r: 9 * k}, gp);
      if (epi.point) {
        const t = el("text", {class: "pred-label", x: p.x + 10 * k, y: p.y + 4 * k,
                              "font-size": 12 * k}, gp);
        t.textContent = `${epi.point}?`;
      }
    }
  }
  for (const pl of state.predictedLines || []) {
    if (pl.view !== v.info.id) continue;
    el("polyline", {class: "pred-line", "data-view": pl.view, "data-line": pl.line,
                    points: pl.points.map((p) => `${p[0]},${p[1]}`).join(" ")}, gp);
  }
}

function renderInfo() {
  const p = state.project;
  document.title = `${p.dirty ? "* " : ""}${p.name} \u2014 photogram measure`;
  ui.projectName.textContent = p.name;
  ui.projectName.title = `${p.project}\ntable: ${p.table}`;
  ui.note.textContent = p.orientation_note || "";
  ui.note.classList.toggle("warn", !p.oriented);
  ui.save.classList.toggle("dirty", !!p.dirty);
  ui.undo.disabled = !p.can_undo;
  clear(ui.points);
  for (const id of p.points.concat([...lineLabels()].filter((l) => !p.points.includes(l)))) {
    const opt = document.createElement("option");
    opt.value = id;
    ui.points.appendChild(opt);
  }
  clear(ui.messages);
  const msgs = (p.messages || []).slice();
  for (const v of p.views) if (!v.ok) msgs.push(v.error || `cannot read the image of ${v.id}`);
  for (const m of msgs) {
    const li = document.createElement("li");
    li.textContent = m;
    ui.messages.appendChild(li);
  }
  renderWorst();
}

function renderWorst() {
  clear(ui.worst);
  const worst = state.project.worst || [];
  ui.worstEmpty.hidden = worst.length > 0;
  for (const r of worst) {
    const li = document.createElement("li");
    if (r.oid !== null && r.oid !== undefined) li.dataset.oid = r.oid;
    li.dataset.view = r.view;
    li.dataset.point = r.point;
    li.textContent = `${r.view} ${r.point} w ${fmt(r.w, 2)}`;
    li.title = `residual (${fmt(r.vx, 3)}, ${fmt(r.vy, 3)}) px, standardized ${fmt(r.w, 2)}`;
    if (r.oid === state.selected) li.classList.add("selected");
    li.addEventListener("click", () => showResidual(r));
    ui.worst.appendChild(li);
  }
}

function renderExposures() {
  const ex = state.project.exposures;
  ui.exposureBox.hidden = !ex || !ex.length;
  if (!ex || !ex.length) { exposure = null; return; }
  if (!ex.includes(exposure)) exposure = ex[0];
  clear(ui.exposure);
  for (const e of ex) {
    const opt = document.createElement("option");
    opt.value = e; opt.textContent = e;
    ui.exposure.appendChild(opt);
  }
  ui.exposure.value = exposure;
}

/** Take a new project body from the server and redraw. */
function setProject(body) {
  const first = state.project === null;
  state.project = body;
  if (state.selected !== null && !observation(state.selected)) {
    state.selected = null;
    state.epipolar = null;
    ui.epiNote.textContent = "";
  }
  if (first) {
    renderExposures();
    buildViews();
  }
  renderInfo();
  drawAll();
  if ((body.lines || []).length) predictLines();      // the ski lines may have changed
}

// ---------------------------------------------------------------- actions

async function select(oid, quiet) {
  state.selected = oid;
  predLabel = null;
  const o = observation(oid);
  drawAll();
  renderWorst();
  if (!o) return;
  if (o.isLine) {
    state.epipolar = null;
    ui.epiNote.textContent = "";
    drawAll();
    if (!quiet) setStatus(`selected a point of line ${o.point} in ${o.view} at ${fmt(o.x, 2)}, ${fmt(o.y, 2)}` +
                          " \u2014 Delete deletes, drag moves");
    return;
  }
  if (!quiet) setStatus(`selected ${o.view} ${o.point} at ${fmt(o.x, 3)}, ${fmt(o.y, 3)}` +
            (o.sigma !== null && o.sigma !== undefined ? `, sigma ${fmt(o.sigma, 3)} px` : "") +
            (o.manual ? " (manual)" : "") + " \u2014 Delete deletes, drag moves, label + Enter relabels");
  await showEpipolar({oid});
}

function deselect() {
  state.selected = null;
  state.epipolar = null;
  ui.epiNote.textContent = "";
  drawAll();
  renderWorst();
}

async function showEpipolar(params) {
  epiSource = params;
  if (!state.project.oriented) {
    state.epipolar = null;
    ui.epiNote.textContent = "no epipolar help: the stations are not oriented";
    drawAll();
    return;
  }
  try {
    const data = await api("GET", `/api/epipolar?${query(params)}`);
    if (epiSource !== params) return;          // a newer request replaced this one
    data.point = params.point || (params.oid !== undefined && observation(params.oid)
      ? observation(params.oid).point : null);
    state.epipolar = data;
    ui.epiNote.textContent = data.note ? `epipolar: ${data.note}` : "";
  } catch (err) {
    state.epipolar = null;
    fail(err);
  }
  drawAll();
}

async function refineAt(view, x, y, point) {
  const r = await api("POST", "/api/refine", {view, x, y, point: point || null});
  state.lastRefine = r;
  return r;
}

function refineText(r) {
  return r.refined ? `refined (${r.method}) to ${fmt(r.x, 3)}, ${fmt(r.y, 3)}, sigma ${fmt(r.sigma, 3)} px`
    : `kept as clicked at ${fmt(r.x, 2)}, ${fmt(r.y, 2)} (manual, sigma ${fmt(r.sigma, 2)} px)`;
}

async function addAt(v, x, y) {
  const label = ui.label.value.trim();
  if (!label) { setStatus("type a label first", true); return; }
  if (lineLabels().has(label)) { addLinePoint(v, x, y, label); return; }
  try {
    const r = await refineAt(v.info.id, x, y, label);
    const body = await api("POST", "/api/edit", {op: "add", view: v.info.id, point: label,
                                                 x: r.x, y: r.y, sigma: r.sigma, manual: !r.refined});
    setProject(body);
    const o = body.observations.find((q) => q.view === v.info.id && q.point === label);
    setStatus(`${v.info.id} ${label}: ${refineText(r)}${r.note ? " \u2014 " + r.note : ""}`);
    if (o) await select(o.oid, true);
  } catch (err) { fail(err); }
}

/** A point of a ski line, kept as clicked (an edge, not a target). */
async function addLinePoint(v, x, y, label) {
  try {
    const body = await api("POST", "/api/edit", {op: "add", view: v.info.id, line: label,
                                                 x, y, sigma: 0.5, manual: true});
    setProject(body);
    const mine = body.lines.filter((p) => p.view === v.info.id && p.line === label);
    setStatus(`${v.info.id}: point of line ${label} added at ${fmt(x, 2)}, ${fmt(y, 2)}`);
    if (mine.length) await select(Math.max(...mine.map((p) => p.oid)), true);
  } catch (err) { fail(err); }
}

async function moveTo(o, x, y) {
  if (o.isLine) {
    try {
      setProject(await api("POST", "/api/edit", {op: "move", oid: o.oid, x, y,
                                                 sigma: o.sigma === undefined ? 0.5 : o.sigma,
                                                 manual: true}));
      setStatus(`${o.view}: point of line ${o.point} moved to ${fmt(x, 2)}, ${fmt(y, 2)}`);
    } catch (err) { fail(err); drawAll(); }
    return;
  }
  try {
    const r = await refineAt(o.view, x, y, o.point);
    const body = await api("POST", "/api/edit", {op: "move", oid: o.oid, x: r.x, y: r.y,
                                                 sigma: r.sigma, manual: !r.refined});
    setProject(body);
    setStatus(`${o.view} ${o.point} moved: ${refineText(r)}`);
    if (observation(o.oid)) await select(o.oid, true);
  } catch (err) { fail(err); drawAll(); }
}

async function deleteSelected() {
  const o = observation(state.selected);
  if (!o) { setStatus("select an observation first (click it)", true); return; }
  try {
    state.selected = null;
    state.epipolar = null;
    setProject(await api("POST", "/api/edit", {op: "delete", oid: o.oid}));
    setStatus(`deleted ${o.view} ${o.point} (Ctrl+Z undoes)`);
  } catch (err) { fail(err); }
}

async function relabelSelected() {
  const o = observation(state.selected);
  const label = ui.label.value.trim();
  if (!o || !label || label === o.point) return;
  try {
    const req = {op: "relabel", oid: o.oid};
    req[o.isLine ? "line" : "point"] = label;
    setProject(await api("POST", "/api/edit", req));
    setStatus(`${o.view}: ${o.point} relabelled ${label}`);
    if (observation(o.oid)) await select(o.oid, true);
  } catch (err) { fail(err); }
}

async function undo() {
  try {
    setProject(await api("POST", "/api/undo"));
    state.epipolar = null;
    ui.epiNote.textContent = "";
    drawAll();
    setStatus("undone");
  } catch (err) { fail(err); }
}

async function save() {
  try {
    const r = await api("POST", "/api/save");
    state.lastSave = r;
    setProject(await api("GET", "/api/project"));
    setStatus(`saved ${r.saved} (${r.rows} rows)` + (r.backup ? `; previous version kept as ${r.backup}` : ""));
  } catch (err) { fail(err); }
}

async function run() {
  const command = ui.runCommand.value;
  ui.run.disabled = true;
  setStatus(`running photogram ${command} \u2026`);
  try {
    const r = await api("POST", "/api/run", {command});
    state.lastRun = r;
    if (r.project) setProject(r.project);
    const s0 = r.sigma0 === null || r.sigma0 === undefined ? "no sigma0" : `sigma0 ${fmt(r.sigma0, 3)}`;
    setStatus(`${command}: ${r.rc === 0 ? "done" : "failed (exit " + r.rc + ")"}, ${s0}` +
              (r.message ? ` \u2014 ${r.message}` : ""), r.rc !== 0);
  } catch (err) {
    fail(err.status === 409 ? `${err.message} (press save first)` : err);
  } finally {
    ui.run.disabled = false;
  }
}

async function showResidual(r) {
  if (exposure !== null) {
    const info = state.project.views.find((v) => v.id === r.view);
    if (info && info.exposure !== exposure) { exposure = info.exposure; ui.exposure.value = exposure; buildViews(); drawAll(); }
  }
  const v = views.get(r.view);
  const o = (r.oid !== null && r.oid !== undefined) ? observation(r.oid)
    : state.project.observations.find((q) => q.view === r.view && q.point === r.point);
  if (!v || !o) return;
  zoomTo(v, o.x, o.y, 80);
  v.svg.scrollIntoView({block: "nearest"});
  await select(o.oid);
}

async function showPredicted(label) {
  const obs = state.project.observations.filter((o) => o.point === label &&
    views.has(o.view));
  if (!obs.length || !state.project.oriented) return;
  predLabel = label;
  await showEpipolar({view: obs[0].view, point: label});
}

let predictGeneration = 0;

/** The predicted ski lines of the exposure shown (drawn dashed). */
async function predictLines() {
  const generation = ++predictGeneration;
  const found = [];
  const labels = new Set();
  for (const p of state.project.lines || []) if (views.has(p.view)) labels.add(p.line);
  if (state.project.oriented) {
    for (const line of labels) {
      try {
        const params = exposure === null ? {line} : {exposure, line};
        const data = await api("GET", `/api/predict_line?${query(params)}`);
        for (const l of data.lines || []) found.push({...l, line});
      } catch (err) { fail(err); }
    }
  }
  if (generation !== predictGeneration) return;        // a newer call took over
  state.predictedLines = found;
  drawAll();
}

// ---------------------------------------------------------------- mouse and keys

function nearest(v, x, y) {
  const k = imagePerScreen(v);
  let best = null, bestD = PICK_PX * k;
  const lines = (state.project.lines || []).filter((p) => p.view === v.info.id).map(linePoint);
  for (const o of state.project.observations.filter((q) => q.view === v.info.id).concat(lines)) {
    const d = Math.hypot(o.x - x, o.y - y);
    if (d <= bestD) { best = o; bestD = d; }
  }
  return best;
}

function attachMouse(v) {
  const svg = v.svg;
  svg.addEventListener("wheel", (evt) => {
    evt.preventDefault();
    const p = toImage(v, evt);
    const f = evt.deltaY < 0 ? 1.25 : 1 / 1.25;
    const w = v.vb.w / f;
    if (w < 4 || w > 8 * (v.info.width || 640)) return;
    const h = v.vb.h / f;
    setViewBox(v, {x: p.x - (p.x - v.vb.x) / f, y: p.y - (p.y - v.vb.y) / f, w, h});
  }, {passive: false});
  svg.addEventListener("contextmenu", (evt) => evt.preventDefault());
  svg.addEventListener("mousedown", (evt) => {
    const pan = evt.button === 1 || (evt.button === 0 && (evt.shiftKey || spaceDown));
    if (evt.button !== 0 && !pan) return;
    evt.preventDefault();
    // keys (Delete, Ctrl+Z) go to the page after a click in a view
    if (document.activeElement && document.activeElement !== document.body) document.activeElement.blur();
    const start = {cx: evt.clientX, cy: evt.clientY, vb: {...v.vb}, p: toImage(v, evt)};
    const hit = pan || evt.altKey ? null : nearest(v, start.p.x, start.p.y);
    let dragging = false;
    if (pan) svg.classList.add("panning");
    const onMove = (e) => {
      const dx = e.clientX - start.cx, dy = e.clientY - start.cy;
      if (pan) {
        const k = imagePerScreen(v);
        setViewBox(v, {...start.vb, x: start.vb.x - dx * k, y: start.vb.y - dy * k});
        // keep k of the start: setViewBox does not change the scale
        return;
      }
      if (hit && (dragging || Math.hypot(dx, dy) > DRAG_PX)) {
        dragging = true;
        const q = toImage(v, e);
        const g = svg.querySelector(`[data-oid="${hit.oid}"]`);
        if (g) g.setAttribute("transform", `translate(${q.x - hit.x} ${q.y - hit.y})`);
      }
    };
    const onUp = (e) => {
      window.removeEventListener("mousemove", onMove);
      window.removeEventListener("mouseup", onUp);
      svg.classList.remove("panning");
      if (pan) return;
      const q = toImage(v, e);
      if (dragging) { moveTo(hit, q.x, q.y); return; }
      if (Math.hypot(e.clientX - start.cx, e.clientY - start.cy) > DRAG_PX) return;
      if (evt.altKey) { state.selected = null; showEpipolar({view: v.info.id, x: q.x, y: q.y}); return; }
      if (hit) { select(hit.oid); return; }
      addAt(v, q.x, q.y);
    };
    window.addEventListener("mousemove", onMove);
    window.addEventListener("mouseup", onUp);
  });
}

function attachKeys() {
  document.addEventListener("keydown", (evt) => {
    const inInput = evt.target instanceof HTMLInputElement || evt.target instanceof HTMLSelectElement;
    if ((evt.ctrlKey || evt.metaKey) && !evt.shiftKey && evt.key.toLowerCase() === "z") {
      if (evt.target === ui.label && ui.label.value) return;    // the box's own text undo
      evt.preventDefault();
      undo();
      return;
    }
    if ((evt.ctrlKey || evt.metaKey) && evt.key.toLowerCase() === "s") {
      evt.preventDefault();
      save();
      return;
    }
    if (inInput) return;
    if (evt.key === "Delete" || evt.key === "Backspace") { evt.preventDefault(); deleteSelected(); }
    else if (evt.key === "Escape") deselect();
    else if (evt.key === " ") { spaceDown = true; evt.preventDefault(); }
  });
  document.addEventListener("keyup", (evt) => { if (evt.key === " ") spaceDown = false; });
  ui.label.addEventListener("keydown", (evt) => {
    if (evt.key !== "Enter") return;
    evt.preventDefault();
    if (state.selected !== null) relabelSelected();
    else showPredicted(ui.label.value.trim());
  });
  ui.label.addEventListener("change", () => {
    const label = ui.label.value.trim();
    if (state.selected === null && label && label !== predLabel) showPredicted(label);
  });
}

// ---------------------------------------------------------------- start

async function start() {
  for (const id of ["status", "note", "messages", "views", "worst", "label", "points", "save",
                    "undo", "run", "exposure"]) ui[id] = document.getElementById(id);
  ui.projectName = document.getElementById("project-name");
  ui.runCommand = document.getElementById("run-command");
  ui.resScale = document.getElementById("res-scale");
  ui.worstEmpty = document.getElementById("worst-empty");
  ui.epiNote = document.getElementById("epi-note");
  ui.exposureBox = document.getElementById("exposure-box");
  ui.save.addEventListener("click", save);
  ui.undo.addEventListener("click", undo);
  ui.run.addEventListener("click", run);
  ui.resScale.addEventListener("input", drawAll);
  ui.exposure.addEventListener("change", () => {
    exposure = ui.exposure.value;
    state.selected = null; state.epipolar = null;
    buildViews(); drawAll(); predictLines();
  });
  const help = document.getElementById("help-button");
  help.addEventListener("click", () => {
    const box = document.getElementById("help");
    box.hidden = !box.hidden;
    help.setAttribute("aria-expanded", String(!box.hidden));
  });
  window.addEventListener("resize", drawAll);
  window.addEventListener("beforeunload", (evt) => {
    if (state.project && state.project.dirty) { evt.preventDefault(); evt.returnValue = ""; }
  });
  attachKeys();
  if (!TOKEN) { setStatus("no token in the address: open the URL that photogram measure --serve printed", true); return; }
  try {
    setProject(await api("GET", "/api/project"));
    setStatus(`${state.project.observations.length} observations in ${state.project.table}`);
    state.ready = true;
  } catch (err) { fail(err); }
}

start();
