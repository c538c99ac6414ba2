// The Kerfmeter page: speaks JSON-RPC 2.0 to `kerfmeter serve` over the WebSocket at /rpc (the
// server's module docs list the methods and notifications). Plain JS, no dependencies, nothing
// fetched from elsewhere: it must work offline. It reconnects by itself when the server restarts.
"use strict";

const $ = (id) => document.getElementById(id);

/* ---------- JSON-RPC over a WebSocket that reconnects ---------- */

/** A JSON-RPC error object ({code, message, data}) as an exception. */
class RpcError extends Error {
  constructor(error) {
    super(error.message ?? "unknown error");
    this.code = error.code;
    this.data = error.data;
  }
}

/** The server's token, if it wants one. Given once as /?token=…, it is kept for this tab only
 * (sessionStorage) and taken out of the address bar, so that it is not left in the history,
 * bookmarks or a screenshot of the page. */
const token = (() => {
  const url = new URL(location.href);
  const given = url.searchParams.get("token");
  if (given) {
    sessionStorage.setItem("kerfmeter-token", given);
    url.searchParams.delete("token");
    history.replaceState(null, "", url.pathname + url.search + url.hash);
  }
  return sessionStorage.getItem("kerfmeter-token");
})();

const METHOD_NOT_FOUND = -32601;
const BUSY = -32001;

const rpc = {
  ws: null,
  nextId: 1,
  pending: new Map(),
  handlers: {},
  retryMs: 500,

  /** ws://HOST/rpc, with the page's token passed on (a browser cannot set a WebSocket's
   * headers). */
  url() {
    const scheme = location.protocol === "https:" ? "wss:" : "ws:";
    return `${scheme}//${location.host}/rpc` + (token ? `?token=${encodeURIComponent(token)}` : "");
  },

  connect() {
    setLink("connecting", "Connecting…");
    const ws = new WebSocket(this.url());
    let opened = false;
    this.ws = ws;
    ws.onopen = () => {
      opened = true;
      this.retryMs = 500;
      setLink("connected", "Connected");
      onConnected();
    };
    ws.onmessage = (event) => this.receive(event.data);
    ws.onclose = () => {
      this.lost(ws);
      if (!opened) this.explainRefusal();
    };
  },

  /** A browser does not say why a WebSocket was refused: ask over HTTP whether a token is
   * missing, and say so instead of only "unreachable". */
  async explainRefusal() {
    try {
      const reply = await fetch("/api/status", { headers: authorization() });
      if (reply.status === 401) {
        setLink("disconnected", "Refused: this server wants a token (open the page as /?token=TOKEN)");
      } else if (reply.status === 403) {
        const body = await reply.json().catch(() => null);
        setLink("disconnected", `Refused: ${body?.error?.message ?? "this server does not answer this page"}`);
      }
    } catch {
      // The server is down: "unreachable" says it.
    }
  },

  /** The connection closed: fail what waits on it and try again, backing off up to 5 s. */
  lost(ws) {
    if (this.ws !== ws) return;
    this.ws = null;
    for (const { reject } of this.pending.values()) {
      const err = new RpcError({ message: "the connection to the server was lost" });
      err.lost = true;
      reject(err);
    }
    this.pending.clear();
    setLink("disconnected", `Server unreachable: retrying in ${(this.retryMs / 1000).toFixed(1)} s`);
    setTimeout(() => this.connect(), this.retryMs);
    this.retryMs = Math.min(this.retryMs * 2, 5000);
  },

  receive(text) {
    let msg;
    try {
      msg = JSON.parse(text);
    } catch {
      showError(new Error("the server sent something that is not JSON"));
      return;
    }
    const waiting = msg.id != null && this.pending.get(msg.id);
    if (waiting) {
      this.pending.delete(msg.id);
      if (msg.error) waiting.reject(new RpcError(msg.error));
      else waiting.resolve(msg.result);
    } else if (typeof msg.method === "string") {
      this.handlers[msg.method]?.(msg.params ?? {});
    } else if (msg.error) {
      showError(new RpcError(msg.error));
    }
  },

  /** Call `method`; resolves with its result, rejects with an RpcError. */
  call(method, params = {}) {
    return new Promise((resolve, reject) => {
      if (!this.ws || this.ws.readyState !== WebSocket.OPEN) {
        reject(new RpcError({ message: "not connected to the server" }));
        return;
      }
      const id = this.nextId++;
      this.pending.set(id, { resolve, reject });
      this.ws.send(JSON.stringify({ jsonrpc: "2.0", id, method, params }));
    });
  },
};

/** The headers that carry the token to the HTTP API. */
function authorization() {
  return token ? { Authorization: `Bearer ${token}` } : {};
}

/* ---------- Messages ---------- */

function setLink(state, text) {
  const link = $("link");
  link.dataset.state = state;
  link.textContent = text;
}

/** Show an error (an RpcError with its code and details, or any Error) until dismissed. */
function showError(err) {
  const p = document.createElement("p");
  let text = err.message;
  if (err instanceof RpcError && err.code != null) {
    const details = [err.data?.kind, err.data?.fault].filter(Boolean).join(", ");
    text += ` (error ${err.code}${details ? `: ${details}` : ""})`;
  }
  p.textContent = text;
  const dismiss = document.createElement("button");
  dismiss.type = "button";
  dismiss.textContent = "Dismiss";
  dismiss.addEventListener("click", () => p.remove());
  p.append(dismiss);
  $("errors").append(p);
}

/** Run `action`, showing any error it throws. */
async function guarded(action) {
  try {
    return await action();
  } catch (err) {
    showError(err);
    return undefined;
  }
}

/** Run a refresh nobody asked for: its errors are shown, but not a lost connection (the
 * header says so already, and everything is fetched again on reconnecting) nor "busy" (the
 * device answers nothing else while a run goes; run_finished fetches again). */
async function background(action) {
  try {
    await action();
  } catch (err) {
    if (!err.lost && err.code !== BUSY) showError(err);
  }
}

/** Fill a <dl> with [term, value] pairs. */
function fillFacts(dl, pairs) {
  dl.replaceChildren();
  for (const [term, value] of pairs) {
    const dt = document.createElement("dt");
    dt.textContent = term;
    const dd = document.createElement("dd");
    dd.textContent = value;
    dl.append(dt, dd);
  }
}

const fmt = (x, digits = 1) => (typeof x === "number" && isFinite(x) ? x.toFixed(digits) : "–");

/* ---------- Device ---------- */

async function refreshInfo() {
  const info = await rpc.call("info");
  const v = info.firmware ?? {};
  const p = info.protocol ?? {};
  const h = info.hardware ?? {};
  fillFacts($("info"), [
    ["Board", h.board ?? "–"],
    ["Firmware", `${v.major}.${v.minor}.${v.patch}`],
    ["Protocol", `${p.major}.${p.minor}`],
    ["Boot id", (info.boot_id >>> 0).toString(16).padStart(8, "0")],
    ["Supply", info.supply_v == null ? "not measured" : `${fmt(info.supply_v, 2)} V`],
  ]);
  $("info").dataset.loaded = "true";
}

async function refreshStatus() {
  showStatus(await rpc.call("status"));
}

function showStatus(s) {
  fillFacts($("status"), [
    ["State", s.state],
    ["Fault", s.fault ?? "none"],
    ["Conditions", s.conditions?.length ? s.conditions.join(", ") : "none"],
    ["Hub", `${fmt(s.angle_deg, 2)}° at ${fmt(s.torque_nm, 3)} N·m`],
    ["Run id", String(s.run_id)],
  ]);
  // Only the user can say where the hub is: offered while the device waits for that.
  $("confirm-zero").hidden = !(s.conditions ?? []).includes("hub-turn-unknown");
}

/** Poll the status while nothing runs (a run streams its own progress). */
function pollStatus() {
  if (!running && rpc.ws?.readyState === WebSocket.OPEN) {
    rpc.call("status").then(showStatus, (err) => {
      if (err.code !== BUSY && !err.lost) showError(err);
    });
  }
}

/* ---------- Measuring ---------- */

let running = false;
/** True while this page's own run_kerfmeter call waits (its result carries the CI and curve). */
let ownRun = false;
const curve = { live: [], sample: -1, final: null };

function setRunning(on) {
  running = on;
  $("measure").disabled = on;
  document.body.dataset.running = String(on);
}

function measureParams() {
  const params = {
    thickness_mm: Number($("thickness").value),
    samples: Number($("samples").value),
  };
  if ($("force").value !== "") params.force_n = Number($("force").value);
  const label = $("label").value.trim();
  if (label) params.label = label;
  return params;
}

async function measure(event) {
  event.preventDefault();
  if (!event.target.reportValidity()) return;
  startCurve();
  setRunning(true);
  ownRun = true;
  $("progress").textContent = "Measuring…";
  try {
    const result = await rpc.call("run_kerfmeter", measureParams());
    showMeasurement(result);
    $("progress").textContent = "Done.";
  } catch (err) {
    $("progress").textContent = "The measurement failed.";
    showError(err);
  } finally {
    ownRun = false;
    setRunning(false);
    pollStatus();
    loadHistory();
  }
}

function startCurve() {
  curve.live = [];
  curve.sample = -1;
  curve.final = null;
  drawCurve();
}

function onProgress(p) {
  if (!running) setRunning(true);
  if (p.sample !== curve.sample) {
    curve.sample = p.sample;
    curve.live = [];
  }
  // The back-off after the release pulls the hub back (a negative torque): it measures the hole
  // play and is not part of the (torque, angle) curve, as on the device.
  if (p.torque_nm >= 0) {
    curve.live.push([p.angle_deg, p.torque_nm]);
    const canvas = $("curve");
    canvas.dataset.livePoints = String(Number(canvas.dataset.livePoints) + 1);
  }
  $("progress").textContent =
    `Gauge ${p.sample + 1} of ${p.samples}: ${p.state}, ${fmt(p.torque_nm, 3)} N·m at ${fmt(p.angle_deg)}°`;
  drawCurve();
}

function drawCurve() {
  const points = curve.final ?? curve.live;
  const canvas = $("curve");
  canvas.dataset.points = String(points.length);
  plot(canvas, [{ name: "torque", color: "#0b5cad", points }], {
    xLabel: "angle, °",
    yLabel: "torque, N·m",
  });
  canvas.setAttribute(
    "aria-label",
    points.length
      ? `Torque–angle curve, ${points.length} points, up to ${fmt(Math.max(...points.map((q) => q[1])), 3)} N·m`
      : "Torque–angle curve: no points yet",
  );
}

/** Show a run_kerfmeter result: the kerf, its confidence interval and the last run's curve. */
function showMeasurement(r) {
  if (r.curve?.points?.length) {
    curve.final = r.curve.points.map(([torque, angle]) => [angle, torque]);
    drawCurve();
  }
  const s = r.summary ?? {};
  const ci = s.ci95_um == null
    ? "One gauge: no confidence interval (measure two or more)."
    : `95 % confidence interval ±${fmt(s.ci95_um)} µm (${fmt(s.mean_um - s.ci95_um)}–${fmt(s.mean_um + s.ci95_um)} µm).`;
  const lines = [
    ci,
    `${s.n} gauge${s.n === 1 ? "" : "s"}, SD ${fmt(s.sd_um)} µm, range ${fmt(s.min_um)}–${fmt(s.max_um)} µm.`,
    `At ${fmt(r.force_n)} N, ${fmt(r.thickness_mm)} mm sheet${r.label ? `, label “${r.label}”` : ""}.`,
  ];
  if (s.outliers?.length) lines.push(`Outliers: gauge ${s.outliers.map((i) => i + 1).join(", ")}.`);
  if (r.curve_error) lines.push(`The curve could not be read: ${r.curve_error}.`);
  const flagged = (r.runs ?? []).filter((run) => flagNames(run.flag_names ?? run.flags).length);
  for (const run of flagged) lines.push(`Run ${run.run_id}: ${flagNames(run.flag_names ?? run.flags).join(", ")}.`);
  showKerf(r.kerf_um, lines, r.runs?.at(-1)?.run_id);
}

/** Show a kerf and lines about it; `runId` is the device's last run behind it. */
function showKerf(kerfUm, lines, runId) {
  const out = $("result");
  out.replaceChildren();
  const kerf = document.createElement("p");
  kerf.className = "kerf";
  kerf.id = "kerf";
  kerf.dataset.kerfUm = String(kerfUm);
  if (runId != null) kerf.dataset.runId = String(runId);
  kerf.textContent = `${fmt(kerfUm)} µm`;
  out.append(kerf);
  for (const line of lines) {
    const p = document.createElement("p");
    p.textContent = line;
    out.append(p);
  }
}

/** A result's or a record's quality flags by name: `flag_names` on a device result (its `flags`
 * are bits), `flags` on a history record. */
function flagNames(flags) {
  if (Array.isArray(flags)) return flags;
  if (typeof flags === "number" && flags !== 0) return [`flags 0x${flags.toString(16)}`];
  if (flags && typeof flags === "object") return Object.keys(flags).filter((k) => flags[k]);
  return [];
}

async function showLastKerf() {
  const last = await rpc.call("get_kerf_value");
  // A run's own result (with its CI) already shown stays: run_finished may follow it.
  if (last && $("kerf")?.dataset.runId !== String(last.run_id)) {
    showKerf(last.kerf_um, [`Last result on the device (run ${last.run_id}).`], last.run_id);
  }
}

/** How long Abort waits for the WebSocket's answer before it asks over HTTP too. */
const ABORT_WAIT_MS = 2000;

/** Stop the motor: over the WebSocket, and by the HTTP API's POST /api/abort when the
 * WebSocket is down or does not answer in time (the reason to press Abort may be the one that
 * broke it). */
function abort() {
  guarded(async () => {
    const overHttp = async () => {
      const reply = await fetch("/api/abort", { method: "POST", headers: authorization() });
      if (!reply.ok) throw new Error(`the server refused to abort (HTTP ${reply.status})`);
    };
    if (rpc.ws?.readyState === WebSocket.OPEN) {
      const late = new Promise((_, reject) =>
        setTimeout(() => reject(new Error("no answer")), ABORT_WAIT_MS));
      try {
        await Promise.race([rpc.call("abort"), late]);
      } catch (e) {
        if (e instanceof RpcError && !e.lost) throw e;
        await overHttp();
      }
    } else {
      await overHttp();
    }
    $("progress").textContent = "Aborted.";
  });
}

/* ---------- History ---------- */

async function loadHistory() {
  const params = { limit: 500 };
  const label = $("history-label").value.trim();
  if (label) params.label = label;
  let history;
  try {
    history = await rpc.call("history", params);
  } catch (err) {
    if (err.lost) return;
    const missing = err.code === METHOD_NOT_FOUND;
    $("history-note").textContent = missing
      ? "This server keeps no history (it has no `history` method)."
      : `History unavailable: ${err.message}`;
    $("history-data").hidden = missing;
    return;
  }
  $("history-data").hidden = false;
  const records = history.records ?? [];
  $("history-note").textContent = records.length ? "" : "No measurements recorded yet.";
  showDrift(history.drift ?? []);
  showHistoryTable(records);
  showHistoryChart(records);
}

function showDrift(drift) {
  const list = $("drift");
  list.replaceChildren();
  for (const d of drift) {
    const li = document.createElement("li");
    li.textContent = d.message ?? `${d.label}: ${fmt(d.kerf_um)} µm, usually ${fmt(d.usual_mean_um)} µm`;
    list.append(li);
  }
}

function showHistoryTable(records) {
  const body = $("history-table").tBodies[0];
  body.replaceChildren();
  for (const r of records) {
    const row = body.insertRow();
    const cells = [
      new Date(r.time).toLocaleString(),
      r.label ?? "",
      fmt(r.thickness_mm, 2),
      fmt(r.force_n),
      fmt(r.kerf_um),
      r.ci95_um == null ? "–" : `±${fmt(r.ci95_um)}`,
      flagNames(r.flags).join(", "),
    ];
    for (const text of cells) row.insertCell().textContent = text;
  }
}

const PALETTE = ["#0b5cad", "#c4420c", "#1b7f3a", "#7b3fb0", "#9a6700", "#0f7f86", "#b42318"];

function showHistoryChart(records) {
  const byLabel = new Map();
  for (const r of records) {
    const t = Date.parse(r.time);
    if (!isFinite(t) || typeof r.kerf_um !== "number") continue;
    const label = r.label || "(no label)";
    if (!byLabel.has(label)) byLabel.set(label, []);
    byLabel.get(label).push([t, r.kerf_um]);
  }
  const series = [...byLabel].map(([name, points], i) => ({
    name,
    color: PALETTE[i % PALETTE.length],
    points: points.sort((a, b) => a[0] - b[0]),
  }));
  const canvas = $("history-chart");
  plot(canvas, series, { xLabel: "time", yLabel: "kerf, µm", xTime: true, markers: true });
  canvas.setAttribute(
    "aria-label",
    series.length
      ? `Kerf over time for ${series.map((s) => `${s.name} (${s.points.length})`).join(", ")}`
      : "Kerf over time per label: no records",
  );
}

/* ---------- Plots ---------- */

/** About five round tick values covering [lo, hi]. */
function ticks(lo, hi) {
  const step0 = (hi - lo) / 5;
  const mag = 10 ** Math.floor(Math.log10(step0));
  const step = [1, 2, 5, 10].map((m) => m * mag).find((s) => s >= step0) ?? 10 * mag;
  const out = [];
  for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) out.push(v);
  return out;
}

function extent(values) {
  let lo = Math.min(...values);
  let hi = Math.max(...values);
  if (!isFinite(lo)) return [0, 1];
  if (hi - lo < 1e-9) {
    const pad = Math.abs(lo) * 0.05 || 1;
    lo -= pad;
    hi += pad;
  }
  return [lo, hi];
}

const DAY_MS = 86400e3;

/** A tick's text; on a time axis, clock times within a day, dates with times within a week,
 * else dates. */
function tickText(v, xTime, span) {
  if (!xTime) return Math.abs(v) >= 100 ? v.toFixed(0) : String(Number(v.toPrecision(3)));
  const date = new Date(v);
  const time = date.toLocaleTimeString(undefined, { hour: "2-digit", minute: "2-digit" });
  const day = date.toLocaleDateString(undefined, { month: "short", day: "numeric" });
  if (span < DAY_MS) return time;
  return span < 7 * DAY_MS ? `${day} ${time}` : day;
}

/** Draw line series ({name, color, points: [[x, y]]}) with axes, ticks and a legend. */
function plot(canvas, series, { xLabel, yLabel, xTime = false, markers = false }) {
  const ctx = canvas.getContext("2d");
  const { width: w, height: h } = canvas;
  const m = { left: 64, right: 16, top: series.length > 1 ? 26 : 12, bottom: 40 };
  ctx.clearRect(0, 0, w, h);
  ctx.font = "12px system-ui, sans-serif";
  const all = series.flatMap((s) => s.points);
  if (!all.length) {
    ctx.fillStyle = "#5c6670";
    ctx.textAlign = "center";
    ctx.fillText("no data yet", w / 2, h / 2);
    ctx.textAlign = "left";
    return;
  }
  const [x0, x1] = extent(all.map((p) => p[0]));
  const [ylo, yhi] = extent(all.map((p) => p[1]).concat(xTime ? [] : [0]));
  const [y0, y1] = [ylo - (yhi - ylo) * 0.05, yhi + (yhi - ylo) * 0.05];
  const sx = (x) => m.left + ((x - x0) / (x1 - x0)) * (w - m.left - m.right);
  const sy = (y) => h - m.bottom - ((y - y0) / (y1 - y0)) * (h - m.top - m.bottom);
  drawAxes(ctx, { w, h, m, x0, x1, y0, y1, sx, sy, xLabel, yLabel, xTime });
  series.forEach((s, i) => {
    ctx.strokeStyle = ctx.fillStyle = s.color;
    ctx.lineWidth = 1.5;
    ctx.beginPath();
    s.points.forEach(([x, y], j) => (j ? ctx.lineTo(sx(x), sy(y)) : ctx.moveTo(sx(x), sy(y))));
    ctx.stroke();
    if (markers) for (const [x, y] of s.points) ctx.fillRect(sx(x) - 2, sy(y) - 2, 4, 4);
    if (series.length > 1) ctx.fillText(`■ ${s.name}`, m.left + 4 + i * 130, 16);
  });
}

function drawAxes(ctx, a) {
  ctx.strokeStyle = "#d5d9de";
  ctx.fillStyle = "#5c6670";
  ctx.lineWidth = 1;
  ctx.textAlign = "right";
  for (const v of ticks(a.y0, a.y1)) {
    ctx.beginPath();
    ctx.moveTo(a.m.left, a.sy(v));
    ctx.lineTo(a.w - a.m.right, a.sy(v));
    ctx.stroke();
    ctx.fillText(tickText(v, false, 0), a.m.left - 6, a.sy(v) + 4);
  }
  ctx.textAlign = "center";
  for (const v of ticks(a.x0, a.x1)) ctx.fillText(tickText(v, a.xTime, a.x1 - a.x0), a.sx(v), a.h - a.m.bottom + 16);
  ctx.textAlign = "right";
  ctx.fillText(a.xLabel, a.w - a.m.right, a.h - 6);
  ctx.save();
  ctx.translate(16, a.m.top);
  ctx.rotate(-Math.PI / 2);
  ctx.fillText(a.yLabel, 0, 0);
  ctx.restore();
  ctx.textAlign = "left";
}

/* ---------- Bed map ---------- */

/** Check a `kerfmeter map` file's shape; returns a message for what is wrong, or null. */
function mapProblem(map) {
  if (!map || !Array.isArray(map.cells)) return "it has no cells";
  const { cols, rows } = map;
  if (!(Number.isInteger(cols) && Number.isInteger(rows) && cols > 0 && rows > 0)) {
    return "it has no grid size";
  }
  if (map.cells.length !== cols * rows) return `${map.cells.length} cells for a ${cols} × ${rows} grid`;
  if (map.cells.some((c) => typeof c.compensation_um !== "number")) return "a cell has no compensation";
  return null;
}

/** Blue (thinner than the reference) through white to red (wider). */
function heat(value, span) {
  const t = Math.max(-1, Math.min(1, value / span));
  const fade = (c) => Math.round(255 - (255 - c) * Math.abs(t));
  return t < 0 ? `rgb(${fade(33)},${fade(102)},${fade(172)})` : `rgb(${fade(178)},${fade(24)},${fade(43)})`;
}

function drawMap(map) {
  const canvas = $("map");
  const ctx = canvas.getContext("2d");
  const { width: w, height: h } = canvas;
  const cw = w / map.cols;
  const ch = (h - 24) / map.rows;
  const span = Math.max(1, ...map.cells.map((c) => Math.abs(c.compensation_um)));
  ctx.clearRect(0, 0, w, h);
  ctx.font = "13px system-ui, sans-serif";
  ctx.textAlign = "center";
  for (const c of map.cells) {
    // Row 0 is the smallest y: draw it at the bottom, as on the bed seen from above.
    const x = c.col * cw;
    const y = (map.rows - 1 - c.row) * ch;
    ctx.fillStyle = heat(c.compensation_um, span);
    ctx.fillRect(x, y, cw, ch);
    ctx.strokeStyle = "#fff";
    ctx.strokeRect(x, y, cw, ch);
    ctx.fillStyle = Math.abs(c.compensation_um) > span / 2 ? "#fff" : "#1d2125";
    const ref = map.reference?.[0] === c.col && map.reference?.[1] === c.row;
    ctx.fillText(`${c.compensation_um >= 0 ? "+" : ""}${fmt(c.compensation_um)} µm${ref ? " (ref)" : ""}`,
      x + cw / 2, y + ch / 2 + 4);
  }
  ctx.textAlign = "left";
  ctx.font = "12px system-ui, sans-serif";
  ctx.fillStyle = "#1d2125";
  ctx.fillText(`reference ${fmt(map.reference_kerf_um)} µm · ${map.bed_width_mm} × ${map.bed_depth_mm} mm bed · ` +
    `red wider, blue narrower`, 4, h - 7);
  canvas.dataset.cells = String(map.cells.length);
  canvas.setAttribute("aria-label", `Bed map, ${map.cols} × ${map.rows} cells: ` +
    map.cells.map((c) => `(${c.col}, ${c.row}) ${fmt(c.compensation_um)} µm`).join("; "));
}

async function loadMap(file) {
  let map;
  try {
    map = JSON.parse(await file.text());
  } catch {
    throw new Error(`${file.name} is not JSON: open a map saved by \`kerfmeter map\``);
  }
  const problem = mapProblem(map);
  if (problem) throw new Error(`${file.name} is not a kerfmeter map: ${problem}`);
  drawMap(map);
}

/* ---------- Plans ---------- */

function planFormat(name) {
  const ext = name.toLowerCase().split(".").pop();
  if (ext === "svg" || ext === "dxf") return ext;
  throw new Error(`${name}: a plan is an .svg or a .dxf file`);
}

/** Dilate a plan by the last kerf and offer the result for download. */
async function dilatePlan(file) {
  const format = planFormat(file.name);
  $("plan-out").textContent = `Dilating ${file.name}…`;
  const out = await rpc.call("dilate", { plan: await file.text(), format, kerf_um: "last" });
  const stem = file.name.replace(/\.[^.]*$/, "");
  const name = `${stem}-k${Math.round(out.kerf_um)}.${out.format ?? format}`;
  // A download, never a document: an SVG opened from a blob: URL would run any script the plan
  // holds with this page's origin (and could reach the device).
  const link = document.createElement("a");
  const previous = $("plan-download");
  if (previous) URL.revokeObjectURL(previous.href);
  link.href = URL.createObjectURL(new Blob([out.content], { type: "application/octet-stream" }));
  link.download = name;
  link.id = "plan-download";
  link.textContent = `Download ${name}`;
  $("plan-out").replaceChildren(`Dilated by ${fmt(out.kerf_um)} µm. `, link);
  link.click();
}

function onPlanFiles(files) {
  const file = files?.[0];
  if (file) {
    guarded(() => dilatePlan(file)).then(() => {
      if (!$("plan-download")) $("plan-out").textContent = "";
    });
  }
}

function setUpDrop() {
  const drop = $("drop");
  drop.addEventListener("dragover", (e) => {
    e.preventDefault();
    drop.classList.add("over");
  });
  drop.addEventListener("dragleave", () => drop.classList.remove("over"));
  drop.addEventListener("drop", (e) => {
    e.preventDefault();
    drop.classList.remove("over");
    onPlanFiles(e.dataTransfer.files);
  });
  drop.addEventListener("keydown", (e) => {
    if (e.key === "Enter" || e.key === " ") $("plan-file").click();
  });
  $("plan-file").addEventListener("change", (e) => {
    onPlanFiles(e.target.files);
    e.target.value = "";
  });
}

/* ---------- Wiring ---------- */

rpc.handlers = {
  progress: onProgress,
  run_started(p) {
    if (!running) startCurve();
    setRunning(true);
    $("progress").textContent = `Measuring${p.label ? ` “${p.label}”` : ""} (started by ${p.by ?? "a client"})…`;
    $("progress").dataset.startedBy = p.by ?? "";
  },
  run_finished(p) {
    setRunning(false);
    if (p.error) $("progress").textContent = `The run ended: ${p.error.message}`;
    else if (!ownRun) background(showLastKerf);
    if (!ownRun) loadHistory();
    if ($("info").dataset.loaded !== "true") background(refreshInfo);
    pollStatus();
  },
  stage(p) {
    $("progress").textContent = `Job: ${p.stage} ${p.state} (${fmt((p.elapsed_ms ?? 0) / 1000)} s)`;
  },
  device(p) {
    const banner = $("device-banner");
    banner.hidden = false;
    banner.dataset.connected = String(p.connected);
    banner.textContent = p.connected
      ? `Device back: ${p.message ?? "reconnected"}`
      : `Device gone: ${p.message ?? "disconnected"}`;
    if (p.connected) background(refreshInfo);
  },
};

/** On every (re)connection: fetch everything afresh. */
function onConnected() {
  background(refreshInfo);
  background(refreshStatus);
  background(showLastKerf);
  loadHistory();
}

function start() {
  $("measure-form").addEventListener("submit", measure);
  $("abort").addEventListener("click", abort);
  $("reset").addEventListener("click", () => guarded(() => rpc.call("reset_kerfmeter").then(refreshStatus)));
  $("clear-fault").addEventListener("click", () => guarded(() => rpc.call("clear_fault").then(refreshStatus)));
  $("confirm-zero").addEventListener("click", () => {
    // The device takes the user's word for it: ask once more, so a stray click gives no false zero.
    const sure = window.confirm(
      "Do the prongs line up with the hub's zero mark (turned there by hand, prongs lifted)? " +
      "The device takes your word for it.");
    if (sure) guarded(() => rpc.call("confirm_hub_at_zero").then(refreshStatus));
  });
  $("self-test").addEventListener("click", () => guarded(async () => {
    $("progress").textContent = "Self-test running…";
    const out = await rpc.call("self_test");
    const failures = (out.failures ?? []).map((f) => `${f.item}: ${f.reason}`);
    $("progress").textContent = out.passed ? "Self-test passed." : `Self-test failed: ${failures.join("; ")}`;
  }));
  $("history-form").addEventListener("submit", (e) => {
    e.preventDefault();
    loadHistory();
  });
  $("map-file").addEventListener("change", (e) => {
    const file = e.target.files?.[0];
    if (file) guarded(() => loadMap(file));
  });
  setUpDrop();
  drawCurve();
  showHistoryChart([]);
  rpc.connect();
  setInterval(pollStatus, 2000);
}

start();
