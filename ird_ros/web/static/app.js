// The designer page: draws the state pushed by the server (GET /state, then WebSocket /ws)
// and sends clicks as POST /answer. Row 0 of every grid is the BOTTOM row of the drawing.
// Two kinds of question: "paths" (options are paths on the test map Rob will drive) and "proxies"
// (options are rewards the designer might have written, each drawn as its plan on the TRAINING
// map, with its weights beside the option's letter). A click sends the option's index either way.
"use strict";

// Every colour comes from IRD_STYLE (colors.js, generated from ird_core/style.py like every picture's).
const TERRAIN_COLORS = IRD_STYLE.terrains;
const UNKNOWN_COLOR = IRD_STYLE.unknown;
const INK = IRD_STYLE.ink, PAPER = IRD_STYLE.paper, NEUTRAL = IRD_STYLE.neutral;

let state = null;
let socket = null;
// The end: the server says so (state.finished) before it stops, or the page gives up after
// MAX_RECONNECTS failed reconnects in a row and says the graph is gone.
const MAX_RECONNECTS = 5;
let failedReconnects = 0;
let ended = null;  // null while the graph runs, else the text of the finished state

const $ = (id) => document.getElementById(id);
const letter = (k) => String.fromCharCode(65 + k);
const pathColor = (k) => IRD_STYLE.options[k % IRD_STYLE.options.length];
const kindOf = (query) => (query && query.kind === "proxies" ? "proxies" : "paths");
// What each kind asks, and the map its options are drawn on.
const KIND_TEXT = {
  paths: {question: "Which path do you prefer?", map: "Test map: where Rob will drive"},
  proxies: {question: "Which reward would you have written for the training world?",
            map: "Training map: where you wrote the reward"},
};
// The map the page draws: the training map for a proxies question, else the test map.
function shownMap() {
  const query = state && state.query;
  return kindOf(query) === "proxies" ? state.train_world : state && state.world;
}

// "#rrggbb" -> [r, g, b] in 0..255.
const rgbOf = (hex) => [1, 3, 5].map((i) => parseInt(hex.slice(i, i + 2), 16));
const withAlpha = (hex, a) => `rgba(${rgbOf(hex).join(", ")}, ${a})`;
// Relative luminance (WCAG 2), as ird_core.style.luminance.
function luminance(hex) {
  const lin = rgbOf(hex).map((v) => { const c = v / 255; return c <= 0.04045 ? c / 12.92 : ((c + 0.055) / 1.055) ** 2.4; });
  return 0.2126 * lin[0] + 0.7152 * lin[1] + 0.0722 * lin[2];
}
// The outline that keeps a line visible on any terrain (ird_core.style.halo_color).
const haloOf = (hex) => (luminance(hex) > 0.5 ? INK : PAPER);
// The risk colour map at fraction t (0..1): linear between IRD_STYLE.risk_stops (ird_core.style.risk_rgb).
function riskColor(t) {
  const stops = IRD_STYLE.risk_stops, x = Math.min(1, Math.max(0, t)) * (stops.length - 1);
  const i = Math.min(stops.length - 2, Math.floor(x)), f = x - i;
  const a = rgbOf(stops[i]), b = rgbOf(stops[i + 1]);
  return `rgb(${a.map((v, k) => Math.round(v + (b[k] - v) * f)).join(", ")})`;
}

function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(attrs)) {
    if (key === "style") Object.assign(node.style, value);
    else if (key === "class") node.className = value;
    else if (key.startsWith("data-")) node.setAttribute(key, value);
    else node[key] = value;
  }
  for (const child of children) node.append(child);
  return node;
}

function showMessage(text, kind) {
  const box = $("message");
  box.textContent = text;
  box.className = "message " + kind;
}

// ------------------------------------------------------------------ drawing

function setupCanvas(canvas) {
  const ratio = window.devicePixelRatio || 1;
  const cssW = canvas.getAttribute("width"), cssH = canvas.getAttribute("height");
  canvas.style.width = cssW + "px";
  canvas.style.height = cssH + "px";
  if (canvas.width !== cssW * ratio) { canvas.width = cssW * ratio; canvas.height = cssH * ratio; }
  const ctx = canvas.getContext("2d");
  ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
  ctx.clearRect(0, 0, cssW, cssH);
  return {ctx, w: Number(cssW), h: Number(cssH)};
}

// Geometry of an H x W grid centred in a w x h canvas; row 0 at the bottom.
function gridGeometry(H, W, w, h) {
  const cell = Math.floor(Math.min(w / W, h / H));
  const x0 = Math.floor((w - cell * W) / 2), y0 = Math.floor((h - cell * H) / 2);
  return {
    cell, x0, y0, H, W,
    cx: (col) => x0 + (col + 0.5) * cell,
    cy: (row) => y0 + (H - 1 - row + 0.5) * cell,
    rect: (row, col) => [x0 + col * cell, y0 + (H - 1 - row) * cell, cell, cell],
  };
}

function terrainColor(world, cls) {
  if (cls === 255 || cls < 0 || cls >= world.class_names.length) return UNKNOWN_COLOR;
  return TERRAIN_COLORS[world.class_names[cls]] || UNKNOWN_COLOR;
}

function drawPaths(ctx, geo, options, widthScale) {
  const q = options.length;
  options.forEach((cells, k) => {
    // Offset each option a little so that shared stretches show every colour.
    const off = (k - (q - 1) / 2) * geo.cell * 0.16;
    const pts = cells.map(([r, c]) => [geo.cx(c) + off, geo.cy(r) + off]);
    ctx.lineJoin = "round"; ctx.lineCap = "round";
    for (const [color, width] of [[haloOf(pathColor(k)), geo.cell * widthScale + 3], [pathColor(k), geo.cell * widthScale]]) {
      ctx.strokeStyle = color; ctx.lineWidth = width;
      ctx.beginPath();
      pts.forEach(([x, y], i) => (i ? ctx.lineTo(x, y) : ctx.moveTo(x, y)));
      ctx.stroke();
    }
  });
}

function drawEndLabels(ctx, geo, options) {
  // Frame the end cell in the option's colour (its terrain stays visible) with a letter badge.
  options.forEach((cells, k) => {
    const [r, c] = cells[cells.length - 1];
    const [x, y, s] = geo.rect(r, c);
    const inset = 2 + 3 * k;
    ctx.strokeStyle = haloOf(pathColor(k)); ctx.lineWidth = 5;
    ctx.strokeRect(x + inset, y + inset, s - 2 * inset, s - 2 * inset);
    ctx.strokeStyle = pathColor(k); ctx.lineWidth = 3;
    ctx.strokeRect(x + inset, y + inset, s - 2 * inset, s - 2 * inset);
    // Badges in different corners, so options ending on the same cell show every letter.
    const rad = Math.max(9, geo.cell * 0.2), corner = [[0, 0], [1, 1], [1, 0], [0, 1]][k % 4];
    const bx = x + (corner[0] ? s - rad - 2 : rad + 2), by = y + (corner[1] ? s - rad - 2 : rad + 2);
    ctx.fillStyle = pathColor(k); ctx.strokeStyle = haloOf(pathColor(k)); ctx.lineWidth = 2;
    ctx.beginPath(); ctx.arc(bx, by, rad, 0, 2 * Math.PI); ctx.fill(); ctx.stroke();
    ctx.fillStyle = haloOf(pathColor(k)); ctx.font = `bold ${Math.round(rad * 1.2)}px sans-serif`;
    ctx.textAlign = "center"; ctx.textBaseline = "middle";
    ctx.fillText(letter(k), bx, by + 1);
  });
}

function drawStart(ctx, geo, start) {
  if (!start) return;
  const x = geo.cx(start[1]), y = geo.cy(start[0]), rad = Math.max(7, geo.cell * 0.24);
  ctx.fillStyle = PAPER; ctx.strokeStyle = INK; ctx.lineWidth = 2.5;
  ctx.beginPath(); ctx.arc(x, y, rad, 0, 2 * Math.PI); ctx.fill(); ctx.stroke();
}

function placeholder(ctx, w, h, text) {
  ctx.fillStyle = NEUTRAL; ctx.font = "14px sans-serif"; ctx.textAlign = "center";
  ctx.fillText(text, w / 2, h / 2);
}

// Fill every cell of an H x W grid with colorAt(row, col).
function fillGrid(ctx, geo, colorAt) {
  for (let r = 0; r < geo.H; r++) {
    for (let c = 0; c < geo.W; c++) {
      ctx.fillStyle = colorAt(r, c);
      ctx.fillRect(...geo.rect(r, c));
    }
  }
}

function drawMap() {
  const {ctx, w, h} = setupCanvas($("map"));
  const world = shownMap(), query = state && state.query, kind = kindOf(query);
  $("map").dataset.map = kind === "proxies" ? "training" : "test";
  $("map-caption").textContent = world ? KIND_TEXT[kind].map : "";
  if (!world) return placeholder(ctx, w, h, kind === "proxies" ? "Waiting for the training map…"
    : "No map yet: waiting for the robot's world.");
  const geo = gridGeometry(world.height, world.width, w, h);
  fillGrid(ctx, geo, (r, c) => terrainColor(world, world.classes[r][c]));
  ctx.strokeStyle = withAlpha(INK, 0.18); ctx.lineWidth = 1;
  for (let r = 0; r <= world.height; r++) {
    ctx.beginPath(); ctx.moveTo(geo.x0, geo.y0 + r * geo.cell); ctx.lineTo(geo.x0 + geo.W * geo.cell, geo.y0 + r * geo.cell); ctx.stroke();
  }
  for (let c = 0; c <= world.width; c++) {
    ctx.beginPath(); ctx.moveTo(geo.x0 + c * geo.cell, geo.y0); ctx.lineTo(geo.x0 + c * geo.cell, geo.y0 + geo.H * geo.cell); ctx.stroke();
  }
  const options = query ? query.options : [];
  drawPaths(ctx, geo, options, 0.16);
  drawStart(ctx, geo, options.length ? options[0][0] : world.start);
  drawEndLabels(ctx, geo, options);
}

function drawRisk() {
  const {ctx, w, h} = setupCanvas($("risk"));
  const risk = state && state.risk_map;
  if (!risk) {
    $("risk-lo").textContent = ""; $("risk-hi").textContent = ""; $("risk-plan").textContent = "";
    return placeholder(ctx, w, h, "No risk map yet");
  }
  // Which risk measure the current plan maximised (the map itself is the reward spread either way).
  $("risk-plan").textContent = risk.plan ? `plan: ${risk.plan.text}` : "plan: none in this world yet";
  const geo = gridGeometry(risk.height, risk.width, w, h);
  // The planner's scale as it is, 0..100 (100 = this map's largest spread), in the pictures' risk colours.
  $("risk-lo").textContent = "0 = sure";
  $("risk-hi").textContent = "100 = most unsure cell";
  fillGrid(ctx, geo, (r, c) => {
    const v = risk.values[r][c];
    return v < 0 ? UNKNOWN_COLOR : riskColor(v / 100);
  });
  const query = state.query;  // the risk map is the test map's: a proxies question's plans are not on it
  if (query && kindOf(query) === "paths" && risk.height === (state.world || {}).height
      && risk.width === (state.world || {}).width) {
    drawPaths(ctx, geo, query.options, 0.12);
    drawStart(ctx, geo, query.options[0][0]);
  }
  ctx.strokeStyle = NEUTRAL; ctx.lineWidth = 1;
  ctx.strokeRect(geo.x0 + 0.5, geo.y0 + 0.5, geo.cell * geo.W - 1, geo.cell * geo.H - 1);
}

function drawLegend() {
  const legend = $("legend");
  legend.replaceChildren();
  // Only the terrains on the map drawn: no gold entry on a map without gold.
  const world = state && shownMap();
  const present = world ? new Set(world.classes.flat()) : null;
  const names = world ? world.class_names.filter((_, cls) => present.has(cls)) : [];
  for (const name of names) {
    legend.append(el("span", {class: "chip"}, el("span", {class: "swatch", style: {background: TERRAIN_COLORS[name] || UNKNOWN_COLOR}}), name));
  }
  legend.append(el("span", {class: "chip"}, el("span", {class: "swatch start"}),
    kindOf(state && state.query) === "proxies" ? "training start" : "Rob's start"));
}

// ------------------------------------------------------------------ text

function terrainAt(r, c) {
  const world = state && shownMap();
  const cls = world && world.classes[r] ? world.classes[r][c] : undefined;
  return cls === undefined || cls === 255 || cls >= world.class_names.length ? "unknown" : world.class_names[cls];
}

const terrainSwatch = (name) => el("span", {class: "swatch", style: {background: TERRAIN_COLORS[name] || UNKNOWN_COLOR}});

// Two lines about a path (its T+1 cells): "ends on <terrain>" and "11 cells: 6 dirt, 5 target",
// each terrain with its map colour.
function pathSummary(cells) {
  if (!state || !shownMap()) return [el("span", {}), el("small", {})];
  const counts = new Map();
  for (const [r, c] of cells) counts.set(terrainAt(r, c), (counts.get(terrainAt(r, c)) || 0) + 1);
  const [r, c] = cells[cells.length - 1];
  const end = el("span", {class: "ends"}, "ends on ", terrainSwatch(terrainAt(r, c)), " " + terrainAt(r, c));
  const parts = el("small", {}, `${cells.length} cells:`);
  for (const [name, n] of counts) parts.append(el("span", {class: "count"}, terrainSwatch(name), ` ${n} ${name}`));
  return [end, parts];
}

// A proxy's weights, one chip per feature ("dirt +0.10"), in the order of proxy_feature_names.
const signed = (v) => `${v >= 0 ? "+" : "−"}${Math.abs(v).toFixed(2)}`;
function proxyWeights(query, k) {
  const weights = (query.option_proxies || [])[k] || [];
  const names = query.proxy_feature_names || weights.map((_, i) => `w${i + 1}`);
  const box = el("span", {class: "weights", "data-option": String(k)}, el("small", {}, "reward: "));
  weights.forEach((v, i) => box.append(el("span", {class: "weight"},
    terrainSwatch(names[i]), ` ${names[i]} `, el("span", {class: "num"}, signed(v)))));
  return box;
}

function renderOptions() {
  const box = $("options");
  box.replaceChildren();
  const query = state && state.query;
  if (!query) {
    box.append(el("p", {class: "sub"}, state && state.finished ? "No more questions: the graph has ended."
      : "No open question. Rob will ask when it is unsure where it is about to drive."));
    $("gain").textContent = "";
    return;
  }
  const pending = state.pending.includes(query.query_id), kind = kindOf(query);
  box.dataset.kind = kind;
  query.options.forEach((cells, k) => {
    const button = el("button", {
      id: `option-${k}`, class: "option", type: "button", disabled: pending,
      "data-query-id": String(query.query_id), "data-option": String(k),
      style: {borderColor: luminance(pathColor(k)) > 0.5 ? INK : pathColor(k)},
      onclick: () => sendAnswer(query.query_id, k),
    },
    el("span", {class: "swatch big", style: {background: pathColor(k)}}),
    el("span", {class: "option-text"}, el("strong", {}, `Option ${letter(k)}`),
      ...(kind === "proxies" ? [proxyWeights(query, k)] : []), ...pathSummary(cells)));
    box.append(button);
  });
  $("gain").textContent = `Expected information from your answer: ${query.information_gain.toFixed(3)} nats` +
    (query.strategy ? ` (options chosen by ${query.strategy.replace("_", " ")})` : "");
}

function renderTitle() {
  const query = state && state.query;
  if (query) {
    const steps = query.options[0].length - 1;
    $("query-title").textContent = `Question #${query.query_id}: ${KIND_TEXT[kindOf(query)].question}`;
    $("query-sub").textContent = kindOf(query) === "proxies"
      ? `Each option is a reward you might have written when you designed Rob's reward on the training map; its line is the path Rob would take there with that reward (${steps} steps from the white circle; the framed cell with the letter is where it ends). Pick the reward you would have written.`
      : `Every path starts at Rob's start (white circle) and takes ${steps} steps; the framed cell with the letter is where it ends.`;
  } else {
    $("query-title").textContent = state && state.world ? "No question right now" : "Waiting for the robot…";
    $("query-sub").textContent = "The page updates by itself when Rob asks.";
  }
}

function renderPosterior() {
  const table = $("posterior");
  table.replaceChildren();
  const post = state && state.posterior;
  if (!post) { $("posterior-sub").textContent = "No posterior yet."; return; }
  const scale = Math.max(1e-9, ...post.mean.map((m, i) => Math.abs(m) + post.std[i]));
  // Gaussian-feature worlds: rows per terrain (the server maps the observation weights), or per
  // observation dimension, said as such, when it cannot.
  const rowName = post.features === "observations" ? "observation dimension" : "terrain";
  table.append(el("tr", {}, el("th", {}, rowName), el("th", {}, "reward (mean ± sd)"), el("th", {}, "")));
  post.feature_names.forEach((name, i) => {
    const m = post.mean[i], s = post.std[i];
    const bar = el("div", {class: "bar-track"},
      el("div", {class: "bar-sd", style: {left: `${50 + 50 * (m - s) / scale}%`, width: `${100 * s / scale}%`}}),
      el("div", {class: "bar-mean " + (m >= 0 ? "pos" : "neg"), style: m >= 0
        ? {left: "50%", width: `${50 * m / scale}%`} : {left: `${50 + 50 * m / scale}%`, width: `${-50 * m / scale}%`}}));
    table.append(el("tr", {},
      el("td", {}, el("span", {class: "swatch", style: {background: TERRAIN_COLORS[name] || UNKNOWN_COLOR}}), " " + name),
      el("td", {class: "num"}, `${m >= 0 ? "+" : "−"}${Math.abs(m).toFixed(2)} ± ${s.toFixed(2)}`),
      el("td", {class: "bar-cell"}, bar)));
  });
  const answers = post.num_answers === 1 ? "1 answer" : `${post.num_answers} answers`;
  $("posterior-sub").textContent = (post.feature_note ? `${post.feature_note}. ` : "") +
    `From the designer's proxy reward and ${answers}; ${post.num_samples} samples (${post.method})` +
    (post.converged === false ? " — sampler NOT converged" : "");
}

function renderHistory() {
  const body = $("history").querySelector("tbody");
  body.replaceChildren();
  const rows = state ? state.history : [];
  if (!rows.length) {
    body.append(el("tr", {}, el("td", {colSpan: 5, class: "sub"}, "No answers yet.")));
    return;
  }
  for (const rec of rows.slice().reverse()) {
    const opts = el("td", {});
    rec.options.forEach((_, k) => opts.append(el("span", {class: "tag", style: {background: pathColor(k), color: haloOf(pathColor(k))}}, letter(k))));
    body.append(el("tr", {id: `history-${rec.query_id}`, "data-query-id": String(rec.query_id)},
      el("td", {}, `#${rec.query_id}`, el("small", {class: "kind"}, kindOf(rec) === "proxies" ? " rewards" : " paths")),
      opts,
      el("td", {class: "num"}, `${rec.information_gain.toFixed(3)} nats`),
      el("td", {}, el("span", {class: "tag", style: {background: pathColor(rec.chosen), color: haloOf(pathColor(rec.chosen))}}, letter(rec.chosen)), ` Option ${letter(rec.chosen)}`),
      el("td", {}, rec.answered_by || "")));
  }
}

let shownQueryId = null;

function render(newState) {
  const queryId = newState.query ? newState.query.query_id : null;
  // A new question starts with a clean slate: the previous answer's message goes away.
  if (queryId !== null && queryId !== shownQueryId && !$("message").classList.contains("info")) {
    $("message").className = "message hidden";
  }
  shownQueryId = queryId;
  state = newState;
  document.body.dataset.version = String(state.version);
  if (state.finished) showFinished(state.finished, "finished");
  renderTitle();
  drawMap();
  drawLegend();
  renderOptions();
  drawRisk();
  renderPosterior();
  renderHistory();
  renderMission();
}

// How the last drive ended (Rob's final status, the navigator's goal outcome), once one has.
function renderMission() {
  const box = $("mission"), mission = state.mission;
  if (!mission) { box.className = "mission hidden"; return; }
  box.textContent = `Mission: ${mission.text}`;
  const bad = (mission.rob && mission.rob.touched_lava) || (mission.goal && mission.goal !== "succeeded");
  box.className = "mission " + (bad ? "bad" : "good");
}

// ------------------------------------------------------------------ server

async function sendAnswer(queryId, chosen) {
  document.querySelectorAll("button.option").forEach((b) => { b.disabled = true; });
  showMessage(`Sending Option ${letter(chosen)} for question #${queryId}… Rob is updating its beliefs (this can take a few seconds).`, "info");
  try {
    const response = await fetch("/answer", {
      method: "POST", headers: {"Content-Type": "application/json"},
      body: JSON.stringify({query_id: queryId, chosen: chosen}),
    });
    const reply = await response.json();
    // The server's thank-you names the option by its letter (never the sampler's statistics).
    showMessage(reply.ok ? reply.message : `Not recorded: ${reply.message}`, reply.ok ? "ok" : "error");
  } catch (err) {
    showMessage(`Not recorded: the server could not be reached (${err}).`, "error");
  }
  if (state) renderOptions();
}

// The finished state: a banner, the connection pill, no question to answer, no more reconnects.
function showFinished(text, kind) {
  if (ended !== null) return;
  ended = text;
  $("finished").textContent = kind === "gone" ? text
    : `${text.charAt(0).toUpperCase()}${text.slice(1)}. Rob asks no more questions; the answers so far are kept.`;
  $("finished").className = "finished " + kind;
  $("connection").textContent = kind === "gone" ? "graph gone" : text.split(":")[0];  // "graph stopped"
  $("connection").className = "connection ended";
  document.querySelectorAll("button.option").forEach((b) => { b.disabled = true; });
}

function connect() {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  socket = new WebSocket(`${scheme}://${location.host}/ws`);
  socket.onopen = () => {
    failedReconnects = 0;
    if (ended === null) { $("connection").textContent = "live"; $("connection").className = "connection online"; }
  };
  socket.onmessage = (event) => render(JSON.parse(event.data));
  socket.onclose = (event) => {
    if (ended !== null) return;  // the server said the graph ended: nothing to reconnect to
    if (event.code === 1013) {  // too many pages open: the server says so; reconnecting would not help
      showFinished(`Not connected: ${event.reason}. Close another page of this designer and reload this one.`, "gone");
      return;
    }
    failedReconnects += 1;  // reset by the next open
    if (failedReconnects > MAX_RECONNECTS) {
      showFinished(`Graph gone: the designer's server has not answered ${MAX_RECONNECTS} reconnects in a row. ` +
        "Reload the page once the graph runs again.", "gone");
      return;
    }
    $("connection").textContent = "reconnecting…"; $("connection").className = "connection offline";
    setTimeout(connect, 1000);
  };
}

// The risk scale's bar: the risk colour map's stops, left (0) to right (100).
document.querySelectorAll(".scale .bar").forEach((bar) => {
  bar.style.background = `linear-gradient(to right, ${IRD_STYLE.risk_stops.join(", ")})`;
});

fetch("/state").then((r) => r.json()).then(render).catch(() => {});
connect();
