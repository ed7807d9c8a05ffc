// quad-control dashboard logic: polls /api/state (JSON) and the image endpoints, draws the floor
// map with trajectory/pose/waypoint, sends operator commands, and renders the point cloud on a
// plain 2D canvas. History plots and the recording viewer are in history.js (uPlot, served locally).
"use strict";

const STATE_PERIOD_MS = 200;   // 5 Hz status: enough for a human, cheap for the server
const MAP_PERIOD_MS = 1000;    // the map changes slowly
const CLOUD_PERIOD_MS = 2000;  // point cloud: a few thousand points every 2 s
const token = new URLSearchParams(location.search).get("token") || "";
const $ = (id) => document.getElementById(id);
let state = null;

function api(path, options = {}) {
  options.headers = Object.assign({}, options.headers || {}, token ? { "X-Dashboard-Token": token } : {});
  return fetch(path, options);
}
function withToken(url) { return token ? url + (url.includes("?") ? "&" : "?") + "token=" + encodeURIComponent(token) : url; }
function fmt(v, digits = 1, unit = "") { return v === null || v === undefined ? "-" : Number(v).toFixed(digits) + unit; }
function message(text, ok = true) { const m = $("message"); m.textContent = text; m.style.color = ok ? "#9fd49f" : "#f28b82"; }

async function post(path, body) {
  try {
    const res = await api(path, { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) });
    const j = await res.json();
    message(j.ok ? path.replace("/api/", "") + ": ok" : j.error, j.ok);
    pollState();
    return j;
  } catch (e) { message("request failed: " + e, false); return null; }
}

// ---- live images: fetch the next one as soon as the previous one has loaded ----
let viewFrames = 0;
function streamImage(img, url) {
  let n = 0;
  const next = () => { img.src = withToken(url + "?n=" + (n++)); };
  img.onload = () => { if (img.id === "rgb") viewFrames++; setTimeout(next, 30); };
  img.onerror = () => setTimeout(next, 500);
  next();
}
streamImage($("rgb"), "/api/rgb.jpg");
streamImage($("depth"), "/api/depth.png");
setInterval(() => { $("view-fps").textContent = viewFrames.toFixed(0); viewFrames = 0; }, 1000);

// ---- status ----
async function pollState() {
  try {
    const res = await api("/api/state");
    if (!res.ok) { message("state: HTTP " + res.status, false); return; }
    state = await res.json();
  } catch (e) { return; }
  window.dispatchEvent(new CustomEvent("qc-state", { detail: state }));  // history plots (history.js)
  const s = state;
  $("state").textContent = s.state;
  $("state").className = "pill " + (s.state === "disarmed" ? "" : (s.state === "lost-hold" ? "bad" : "ok"));
  $("tracking").textContent = "tracking: " + (s.tracking ? "yes" : "no") + " (" + s.slam.state + ")";
  $("tracking").className = "pill " + (s.tracking ? "ok" : "bad");
  $("last-event").textContent = s.last_event;
  $("frame-seq").textContent = "frame " + s.stream.sequence + " (" + s.stream.frames + " received)";
  $("fps").textContent = fmt(s.stream.fps, 1);
  $("lat-stream").textContent = fmt(s.stream.latency_ms, 1, " ms");
  $("lat-slam").textContent = fmt(s.slam.latency_ms, 1, " ms");
  $("slam-info").textContent = s.slam.processed + " done, " + s.slam.dropped_busy + " dropped busy, " + s.slam.inliers + " inliers";
  const fw = s.firmware;
  if (!fw.enabled) {
    $("lat-firmware").textContent = "disabled"; $("fw-info").textContent = "link disabled"; $("imu-info").textContent = "-";
  } else {
    $("lat-firmware").textContent = fmt(fw.latency_ms, 1, " ms") + " (mean " + fmt(fw.mean_latency_ms, 1) + ")";
    $("fw-info").textContent = (fw.connected ? "connected" : "NOT connected") + ", craft " + (fw.reply ? fw.reply.state : "?") +
      ", sent " + fw.sent + ", ok " + fw.ok + ", timeouts " + fw.timeouts + ", errors " + fw.http_errors +
      (fw.last_error ? " | " + fw.last_error : "");
    $("imu-info").textContent = fw.reply ? "att mrad " + fw.reply.att_mrad.join(", ") + " | frame match " + fmt(fw.imu_match_dt_ms, 1, " ms") : "-";
  }
  const c = s.command;
  $("cmd-roll").textContent = fmt(c.roll_pct, 1, " %");
  $("cmd-pitch").textContent = fmt(c.pitch_pct, 1, " %");
  $("cmd-yaw").textContent = fmt(c.yaw_pct, 1, " %");
  $("cmd-throttle").textContent = fmt(c.throttle_pct, 1, " %");
  $("cmd-pwm").textContent = c.pwm_us.join(" / ") + (c.armed ? " (armed)" : " (disarmed)");
  $("waypoint").textContent = s.waypoint ? fmt(s.waypoint.x_m, 2) + ", " + fmt(s.waypoint.y_m, 2) + " m" + (s.facing_waypoint ? " (moving)" : " (turning)") : "none";
  $("pose-info").textContent = s.pose ? "pose x " + fmt(s.pose.x_m, 2) + " y " + fmt(s.pose.y_m, 2) + " z " + fmt(s.pose.z_m, 2) + " m, yaw " + fmt(s.pose.yaw_deg, 0) + " deg" : "pose -";
  $("floor-info").textContent = s.floor.found ? "floor found, camera " + fmt(s.floor.height_m, 2) + " m above it (" + fmt(100 * s.floor.inlier_fraction, 0) + " % inliers)" : (s.floor.fallback ? "no floor in view: level from the mount angle, height from start" : "searching floor...");
  drawMap();
}
setInterval(pollState, STATE_PERIOD_MS);
pollState();

// ---- floor map ----
const mapImage = new Image();
let mapView = { cx: 0, cy: 0, mPerPx: 0.02 };   // view centre (world m) and scale
function refreshMap() { mapImage.src = withToken("/api/map.png?n=" + Date.now()); }
mapImage.onload = drawMap;
setInterval(refreshMap, MAP_PERIOD_MS);
refreshMap();

function worldToCanvas(x, y) {
  const cv = $("map");
  return [cv.width / 2 + (x - mapView.cx) / mapView.mPerPx, cv.height / 2 - (y - mapView.cy) / mapView.mPerPx];
}
function canvasToWorld(px, py) {
  const cv = $("map");
  return [mapView.cx + (px - cv.width / 2) * mapView.mPerPx, mapView.cy - (py - cv.height / 2) * mapView.mPerPx];
}

function drawMap() {
  const cv = $("map"), g = cv.getContext("2d");
  g.fillStyle = "#000"; g.fillRect(0, 0, cv.width, cv.height);
  if (!state) return;
  const m = state.map;
  if (state.pose) { mapView.cx = state.pose.x_m; mapView.cy = state.pose.y_m; }
  if (mapImage.complete && mapImage.naturalWidth > 0) {
    // Image row 0 = max y (north up); cell size = resolution.
    const [x0, y0] = worldToCanvas(m.origin_x_m, m.origin_y_m + m.height_cells * m.resolution_m);
    const size = m.width_cells * m.resolution_m / mapView.mPerPx;
    g.imageSmoothingEnabled = false;
    g.drawImage(mapImage, x0, y0, size, size);
  }
  // 1 m grid
  g.strokeStyle = "rgba(255,255,255,0.08)"; g.lineWidth = 1;
  for (let k = -20; k <= 20; k++) {
    const [ax, ay] = worldToCanvas(Math.round(mapView.cx) + k, 0), [bx, by] = worldToCanvas(0, Math.round(mapView.cy) + k);
    g.beginPath(); g.moveTo(ax, 0); g.lineTo(ax, cv.height); g.stroke();
    g.beginPath(); g.moveTo(0, by); g.lineTo(cv.width, by); g.stroke();
  }
  // trajectory
  g.strokeStyle = "#4fc3f7"; g.lineWidth = 2; g.beginPath();
  state.trajectory.forEach((p, i) => { const [x, y] = worldToCanvas(p[0], p[1]); if (i) g.lineTo(x, y); else g.moveTo(x, y); });
  g.stroke();
  // setpoint
  if (state.state !== "disarmed" && state.state !== "armed") {
    const [sx, sy] = worldToCanvas(state.setpoint.x_m, state.setpoint.y_m);
    g.strokeStyle = "#ffd54f"; g.beginPath(); g.arc(sx, sy, 6, 0, 2 * Math.PI); g.stroke();
  }
  // waypoint
  if (state.waypoint) {
    const [wx, wy] = worldToCanvas(state.waypoint.x_m, state.waypoint.y_m);
    g.strokeStyle = "#ea80fc"; g.lineWidth = 3;
    g.beginPath(); g.moveTo(wx - 9, wy - 9); g.lineTo(wx + 9, wy + 9); g.moveTo(wx + 9, wy - 9); g.lineTo(wx - 9, wy + 9); g.stroke();
    g.beginPath(); g.arc(wx, wy, 12, 0, 2 * Math.PI); g.stroke();
  }
  // craft: arrow along the heading
  if (state.pose) {
    const [px, py] = worldToCanvas(state.pose.x_m, state.pose.y_m);
    const a = state.pose.yaw_deg * Math.PI / 180;
    g.fillStyle = "#69f0ae"; g.beginPath();
    g.moveTo(px + 12 * Math.cos(a), py - 12 * Math.sin(a));
    g.lineTo(px + 6 * Math.cos(a + 2.5), py - 6 * Math.sin(a + 2.5));
    g.lineTo(px + 6 * Math.cos(a - 2.5), py - 6 * Math.sin(a - 2.5));
    g.closePath(); g.fill();
  }
  g.fillStyle = "#9aa0a8"; g.font = "11px sans-serif";
  g.fillText("1 m grid, north up; red obstacle, blue path, pink waypoint", 6, cv.height - 6);
}

$("map").addEventListener("click", (ev) => {
  const r = $("map").getBoundingClientRect();
  const [x, y] = canvasToWorld(ev.clientX - r.left, ev.clientY - r.top);
  post("/api/waypoint", { x_m: x, y_m: y });
});

// ---- operator buttons and manual keys ----
for (const [id, cmd] of [["btn-arm", "arm"], ["btn-takeoff", "takeoff"], ["btn-land", "land"], ["btn-disarm", "disarm"]]) {
  $(id).addEventListener("click", () => post("/api/command", { command: cmd }));
}
const STEP_M = 0.1, STEP_DEG = 10;  // matches controller.manual_step_m / manual_yaw_step_deg defaults
const KEYS = {
  w: { forward_m: STEP_M }, s: { forward_m: -STEP_M }, a: { left_m: STEP_M }, d: { left_m: -STEP_M },
  q: { yaw_ccw_deg: STEP_DEG }, e: { yaw_ccw_deg: -STEP_DEG }, r: { up_m: STEP_M }, f: { up_m: -STEP_M },
};
document.addEventListener("keydown", (ev) => {
  const step = KEYS[ev.key.toLowerCase()];
  if (step && !ev.repeat) post("/api/manual", step);
});

// ---- 3D point cloud (plain canvas, orthographic, drag to rotate) ----
let cloud = { points: [], total: 0 }, yaw = -0.6, pitch = 0.5, zoom = 60, drag = null;
async function refreshCloud() {
  try { const res = await api("/api/cloud?max=6000"); if (res.ok) { cloud = await res.json(); drawCloud(); } } catch (e) { /* retry later */ }
}
function drawCloud() {
  const cv = $("cloud"), g = cv.getContext("2d");
  g.fillStyle = "#000"; g.fillRect(0, 0, cv.width, cv.height);
  // Rotate about the centroid of the cloud so it stays in view.
  const c = [0, 0, 0];
  for (const p of cloud.points) { c[0] += p[0]; c[1] += p[1]; c[2] += p[2]; }
  if (cloud.points.length) { c[0] /= cloud.points.length; c[1] /= cloud.points.length; c[2] /= cloud.points.length; }
  const cy = Math.cos(yaw), sy = Math.sin(yaw), cp = Math.cos(pitch), sp = Math.sin(pitch);
  const proj = cloud.points.map((p) => {
    const x = p[0] - c[0], y = p[1] - c[1], z = p[2] - c[2];
    const xr = cy * x - sy * y, yr = sy * x + cy * y;       // about z (up)
    const depth = cp * yr + sp * z, up = -sp * yr + cp * z;  // tilt
    return [cv.width / 2 + zoom * xr, cv.height / 2 - zoom * up, depth, p];
  }).sort((a, b) => b[2] - a[2]);
  for (const [x, y, , p] of proj) { g.fillStyle = "rgb(" + p[3] + "," + p[4] + "," + p[5] + ")"; g.fillRect(x, y, 2, 2); }
  $("cloud-info").textContent = cloud.points.length + " of " + cloud.total + " points";
}
$("cloud").addEventListener("mousedown", (ev) => { drag = [ev.clientX, ev.clientY]; });
window.addEventListener("mouseup", () => { drag = null; });
window.addEventListener("mousemove", (ev) => {
  if (!drag) return;
  yaw += (ev.clientX - drag[0]) * 0.01; pitch = Math.max(-1.5, Math.min(1.5, pitch + (ev.clientY - drag[1]) * 0.01));
  drag = [ev.clientX, ev.clientY]; drawCloud();
});
$("cloud").addEventListener("wheel", (ev) => { ev.preventDefault(); zoom *= ev.deltaY < 0 ? 1.1 : 0.9; drawCloud(); });
setInterval(refreshCloud, CLOUD_PERIOD_MS);
refreshCloud();
$("ply-link").href = withToken("/api/map.ply");
