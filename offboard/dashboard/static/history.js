// quad-control dashboard history: time-series plots (uPlot, installed by make deps and served by
// quad-control) of the last minutes of /api/state - height vs setpoint, position error, tracking,
// stream fps, capture -> command latency - and the same plots from a recording (.mcap) loaded in the
// page, with a slider that scrubs through it and shows the recorded camera image at that time.
// The MCAP reader below follows https://mcap.dev/spec: top-level records in file order, chunks
// decompressed with fzstd (zstd) or stored; a cut or damaged file is read up to the damage and says
// where it stopped. Nothing is fetched from outside the project.
"use strict";

const HISTORY_S = 300;          // live plots keep the last 5 minutes
const PLOT_HEIGHT_PX = 130;
const PLOT_MIN_WIDTH_PX = 400;
// capture -> command compares the sensor's capture stamp with the ground station's clock: only
// meaningful when both share a clock (the HIL rig; a TUM replay's stamps are from 2011). Outside
// 0..10 s the clocks are not comparable and the point is left out.
const MAX_COMPARABLE_LATENCY_MS = 10000;
function latency(v) { return v === null || v === undefined || v < 0 || v > MAX_COMPARABLE_LATENCY_MS ? null : v; }
const qcHistory = { live: [], recording: null };   // exposed for the browser tests
window.qcHistory = qcHistory;

// One plot per quantity; `pick` reads a live /api/state sample, `fromRec` names the recorded field.
const PLOTS = [
  { id: "height", title: "height vs setpoint (m)", series: ["height", "setpoint"],
    pick: (s) => [s.pose ? s.pose.z_m : null, s.setpoint.z_m] },
  { id: "poserr", title: "position error (m)", series: ["|pose - setpoint|"],
    pick: (s) => [s.pose ? Math.hypot(s.pose.x_m - s.setpoint.x_m, s.pose.y_m - s.setpoint.y_m, s.pose.z_m - s.setpoint.z_m) : null] },
  { id: "tracking", title: "tracking (1 = tracked)", series: ["tracking"], stepped: true,
    pick: (s) => [s.tracking ? 1 : 0] },
  { id: "fps", title: "stream fps", series: ["fps"], pick: (s) => [s.stream.fps] },
  { id: "latency", title: "latency (ms): capture -> command sent, pose -> command, SLAM", series: ["capture->command", "pose->command", "SLAM"],
    pick: (s) => [latency(s.recording && s.recording.capture_to_command_ms), s.recording && s.recording.pose_to_command_ms, s.slam.latency_ms] },
];
const COLOURS = ["#8ab4f8", "#f6c26b", "#9fd49f"];

function haveUplot() { return typeof window.uPlot === "function"; }

function makePlots(container, syncKey, timeScale) {
  container.innerHTML = "";
  if (!haveUplot()) {
    container.textContent = "uPlot is not installed: run make deps (deps/post/dashboard.sh)";
    return [];
  }
  const cols = Math.max(1, Math.floor(container.clientWidth / PLOT_MIN_WIDTH_PX));
  const width = Math.floor(container.clientWidth / cols) - 8;
  return PLOTS.map((p) => {
    const div = document.createElement("div");
    div.className = "plot";
    div.dataset.plot = p.id;
    container.appendChild(div);
    const series = [{}].concat(p.series.map((label, i) => ({
      label, stroke: COLOURS[i % COLOURS.length], width: 1.5, spanGaps: false,
      paths: p.stepped ? uPlot.paths.stepped({ align: 1 }) : undefined,
    })));
    const opts = {
      title: p.title, width, height: PLOT_HEIGHT_PX, series,
      scales: { x: { time: timeScale } },
      axes: [{ stroke: "#9aa0a8", grid: { stroke: "#333" } }, { stroke: "#9aa0a8", grid: { stroke: "#333" } }],
      cursor: { sync: { key: syncKey } },
      legend: { live: true },
    };
    return new uPlot(opts, [[]].concat(p.series.map(() => [])), div);
  });
}

// ---- live ----------------------------------------------------------------------------------------
let livePlots = null;
window.addEventListener("qc-state", (e) => {
  const s = e.detail;
  const t = Date.now() / 1000;
  qcHistory.live.push({ t, values: PLOTS.map((p) => p.pick(s)) });
  while (qcHistory.live.length && qcHistory.live[0].t < t - HISTORY_S) qcHistory.live.shift();
  const rec = s.recording || {};
  document.getElementById("rec-info").textContent = rec.enabled
    ? (rec.failed ? "recording STOPPED: " + rec.error : "recording " + rec.file + ", " + (rec.bytes / 1048576).toFixed(1) + " MB, " +
      rec.messages + " messages, dropped " + rec.dropped_queue_full)
    : "not recording";
});
function drawLive() {
  if (!livePlots) livePlots = makePlots(document.getElementById("history-live"), "live", true);
  const h = qcHistory.live;
  livePlots.forEach((u, k) => {
    const data = [h.map((x) => x.t)];
    PLOTS[k].series.forEach((_, j) => data.push(h.map((x) => nullable(x.values[k][j]))));
    u.setData(data);
  });
}
function nullable(v) { return v === undefined || v === null || !Number.isFinite(v) ? null : v; }
setInterval(drawLive, 1000);

// ---- MCAP reading (spec: Records) ------------------------------------------------------------------
const OP = { SCHEMA: 0x03, CHANNEL: 0x04, MESSAGE: 0x05, CHUNK: 0x06, DATA_END: 0x0f, FOOTER: 0x02 };
const MAGIC = [0x89, 0x4d, 0x43, 0x41, 0x50, 0x30, 0x0d, 0x0a];
const TELEMETRY = new Set(["/slam/tracking", "/stream/frame", "/control/command", "/latency", "/events", "/camera/rgb/compressed"]);

function readMcap(bytes) {
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const out = { channels: new Map(), messages: [], errors: [], complete: false };
  if (bytes.length < 8 || MAGIC.some((b, i) => bytes[i] !== b)) { out.errors.push("not an MCAP file (bad magic)"); return out; }
  const u64 = (v, at) => Number(v.getBigUint64(at, true));
  const str = (v, b, at) => { const n = v.getUint32(at, true); return [new TextDecoder().decode(b.subarray(at + 4, at + 4 + n)), at + 4 + n]; };
  const records = (b, v, start, end, inChunk) => {
    let pos = start;
    while (pos < end) {
      if (pos + 9 > end) { out.errors.push("truncated at byte " + pos + ": record header cut"); return false; }
      const op = b[pos], len = u64(v, pos + 1), body = pos + 9;
      if (body + len > end) { out.errors.push("truncated at byte " + pos + ": record 0x" + op.toString(16) + " needs " + len + " bytes"); return false; }
      if (op === OP.CHANNEL) {
        const id = v.getUint16(body, true);
        const [topic] = str(v, b, body + 4);
        out.channels.set(id, topic);
      } else if (op === OP.MESSAGE) {
        const topic = out.channels.get(v.getUint16(body, true));
        if (TELEMETRY.has(topic)) {
          const t_ns = u64(v, body + 6);
          try { out.messages.push({ topic, t: t_ns / 1e9, data: JSON.parse(new TextDecoder().decode(b.subarray(body + 22, body + len))) }); }
          catch (e) { out.errors.push("message at byte " + pos + " is not JSON"); }
        }
      } else if (op === OP.CHUNK && !inChunk) {
        let at = body + 8 + 8 + 8 + 4;
        let compression;
        [compression, at] = str(v, b, at);
        const size = u64(v, at);
        const raw = b.subarray(at + 8, at + 8 + size);
        try {
          const plain = compression === "zstd" ? fzstd.decompress(raw) : raw;
          records(plain, new DataView(plain.buffer, plain.byteOffset, plain.byteLength), 0, plain.length, true);
        } catch (e) { out.errors.push("damaged chunk at byte " + pos + " skipped: " + e); }
      } else if (op === OP.FOOTER) { out.complete = true; return true; }
      pos = body + len;
    }
    return true;
  };
  records(bytes, view, 8, bytes.length, false);
  return out;
}

// ---- recording view --------------------------------------------------------------------------------
let recPlots = null;
function loadRecording(bytes, name) {
  const r = readMcap(bytes);
  const byTopic = (t) => r.messages.filter((m) => m.topic === t);
  const t0 = r.messages.length ? Math.min(...r.messages.map((m) => m.t)) : 0;
  const rel = (m) => m.t - t0;
  const tracking = byTopic("/slam/tracking"), frames = byTopic("/stream/frame");
  const commands = byTopic("/control/command").filter((m) => m.data.capture_to_command_ms !== undefined);
  const stageLatency = byTopic("/latency");
  const err = (d) => d.pose ? Math.hypot(d.pose.x_m - d.setpoint.x_m, d.pose.y_m - d.setpoint.y_m, d.pose.z_m - d.setpoint.z_m) : null;
  // Every plot on its own x samples, merged into one x axis (uPlot wants a shared x).
  const sources = [
    [tracking, (d) => [d.pose ? d.pose.z_m : null, d.setpoint.z_m]],
    [tracking, (d) => [err(d)]],
    [tracking, (d) => [d.tracking ? 1 : 0]],
    [frames, (d) => [d.fps]],
    [commands.concat(stageLatency), (d) => [latency(d.capture_to_command_ms), nullable(d.pose_to_command_ms), nullable(d.slam_ms)]],
  ];
  qcHistory.recording = { name, messages: r.messages.length, errors: r.errors, complete: r.complete, t_end: 0,
                          images: byTopic("/camera/rgb/compressed").map((m) => ({ t: rel(m), data: m.data })) };
  recPlots = makePlots(document.getElementById("history-rec"), "rec", false);
  sources.forEach(([msgs, f], k) => {
    const sorted = msgs.slice().sort((a, b) => a.t - b.t);
    const data = [sorted.map(rel)];
    PLOTS[k].series.forEach((_, j) => data.push(sorted.map((m) => nullable(f(m.data)[j]))));
    if (recPlots[k]) recPlots[k].setData(data);
    qcHistory.recording.t_end = Math.max(qcHistory.recording.t_end, data[0].length ? data[0][data[0].length - 1] : 0);
  });
  const slider = document.getElementById("rec-scrub");
  slider.max = String(qcHistory.recording.t_end);
  slider.step = "0.05";
  slider.value = "0";
  slider.disabled = false;
  const events = byTopic("/events").length;
  document.getElementById("rec-status").textContent = name + ": " + r.messages.length + " messages (" + events + " events), " +
    qcHistory.recording.t_end.toFixed(1) + " s" + (r.complete ? "" : ", NOT closed (read up to the cut)") +
    (r.errors.length ? " | " + r.errors.join("; ") : "");
  scrub(0);
}

function scrub(t) {
  const rec = qcHistory.recording;
  if (!rec) return;
  document.getElementById("rec-time").textContent = "t = " + t.toFixed(2) + " s";
  (recPlots || []).forEach((u) => {
    const left = u.valToPos(t, "x");
    if (Number.isFinite(left)) u.setCursor({ left, top: 10 });
  });
  let best = null;
  for (const im of rec.images) if (im.t <= t + 1e-6) best = im;
  const img = document.getElementById("rec-image");
  // data-t at full precision: it is compared with the scrubber's value (2 decimals could round past it).
  if (best) { img.src = "data:image/jpeg;base64," + best.data.data; img.dataset.t = String(best.t); }
}

document.getElementById("rec-file").addEventListener("change", async (e) => {
  const f = e.target.files[0];
  if (!f) return;
  document.getElementById("rec-status").textContent = "reading " + f.name + " ...";
  loadRecording(new Uint8Array(await f.arrayBuffer()), f.name);
});
document.getElementById("rec-scrub").addEventListener("input", (e) => scrub(Number(e.target.value)));
