// rsi operator console (issue 16). One module, no framework; three.js is the only library (vendored).
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";

const TOKEN = document.querySelector('meta[name="rsi-token"]').content;
const HEARTBEAT_MS = 50; // 20 Hz hold-to-move heartbeat; the server stops the arm when it goes quiet
const CAMERAS = ["raw", "compensated", "overview"];
const REGION_COLOURS = { A: "#ff1744", B: "#ff6d00", C: "#ffab00", D: "#ffee58", E: "#9ccc65", F: "#26a69a", "-": "#607d8b" };
const $ = (id) => document.getElementById(id);
const q = (path) => `${path}${path.includes("?") ? "&" : "?"}token=${encodeURIComponent(TOKEN)}`;
const wsUrl = (path) => `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}${q(path)}`;

// What the browser tests read (frame rates and ages measured in the page).
const stats = { fps: {}, age: {}, frames: {}, status: null, controlling: false, replies: [] };
window.rsiConsole = stats;

async function api(path, options = {}) {
  const response = await fetch(path, {
    ...options,
    headers: { Authorization: `Bearer ${TOKEN}`, "Content-Type": "application/json", ...(options.headers || {}) },
  });
  const body = await response.json().catch(() => ({}));
  if (!response.ok) throw new Error(body.detail || `${response.status}`);
  return body;
}
const post = (path, body) => api(path, { method: "POST", body: JSON.stringify(body || {}) });
const fmt = (x, digits = 3) => (x === null || x === undefined ? "-" : Number(x).toFixed(digits));

// ------------------------------------------------------------------------------------------ video
const frameTimes = Object.fromEntries(CAMERAS.map((c) => [c, []]));
const lastUrl = {};
function connectVideo() {
  const socket = new WebSocket(wsUrl("/ws/video"));
  socket.binaryType = "arraybuffer";
  socket.onmessage = (event) => {
    const view = new DataView(event.data);
    for (let at = 0; at < event.data.byteLength;) {
      const length = view.getUint32(at + 13, true);
      showFrame(CAMERAS[view.getUint8(at)], view.getFloat64(at + 5, true), event.data.slice(at + 17, at + 17 + length));
      at += 17 + length;
    }
    socket.send("shown"); // the server sends the next frames only to a page that keeps up (AckWindow)
  };
  socket.onclose = () => setTimeout(connectVideo, 1000);
}
function showFrame(camera, renderedMs, jpeg) {
  const url = URL.createObjectURL(new Blob([jpeg], { type: "image/jpeg" }));
  const img = $(`cam-${camera}`);
  img.src = url;
  if (lastUrl[camera]) URL.revokeObjectURL(lastUrl[camera]);
  lastUrl[camera] = url;
  const now = performance.now();
  const times = frameTimes[camera];
  times.push(now);
  while (times.length && now - times[0] > 2000) times.shift();
  stats.frames[camera] = (stats.frames[camera] || 0) + 1;
  stats.age[camera] = Date.now() - renderedMs;
}
setInterval(() => {
  const now = performance.now();
  for (const camera of CAMERAS) {
    const times = frameTimes[camera].filter((t) => now - t <= 2000);
    const fps = times.length > 1 ? ((times.length - 1) * 1000) / (times[times.length - 1] - times[0]) : 0;
    stats.fps[camera] = fps;
    $(`fps-${camera}`).textContent = `${fps.toFixed(1)} fps`;
    const age = stats.age[camera];
    const badge = $(`age-${camera}`);
    badge.textContent = age === undefined ? "-" : `${Math.round(age)} ms old`;
    badge.className = `badge age ${age === undefined ? "" : age < 150 ? "ok" : age < 500 ? "warn" : "bad"}`;
  }
}, 250);

// ------------------------------------------------------------------------------------------ control
let control = null;
let controlling = false;
const command = { stick: [0, 0], lift: 0, keys: new Set(), pad: [0, 0, 0] };
let heartbeat = null;

function connectControl() {
  control = new WebSocket(wsUrl("/ws/control"));
  control.onmessage = (event) => {
    const reply = JSON.parse(event.data);
    stats.replies.push(reply);
    if (reply.type === "acquire") setControlling(reply.granted);
  };
  control.onclose = () => {
    setControlling(false);
    setTimeout(connectControl, 1000);
  };
}
stats.closeControl = () => control && control.close(); // the browser test's "lost socket"
function send(message) {
  if (control && control.readyState === WebSocket.OPEN) control.send(JSON.stringify(message));
}
function setControlling(value) {
  controlling = value;
  stats.controlling = value;
  $("acquire").hidden = value;
  $("leave").hidden = !value;
  $("role").textContent = value ? "you drive" : "watching";
  $("role").className = `badge ${value ? "ok" : ""}`;
}
function velocity() {
  // tool frame, m/s: x across the view, y up in the view, z toward the surface (the law's sign)
  const speed = stats.status ? stats.status.teleop.joystick_speed_m_s : 0.05;
  const key = (plus, minus) => (command.keys.has(plus) ? 1 : 0) - (command.keys.has(minus) ? 1 : 0);
  const clamp = (v) => Math.max(-1, Math.min(1, v));
  const x = clamp(command.stick[0] + key("d", "a") + command.pad[0]);
  const y = clamp(command.lift + key("r", "f") + command.pad[1]);
  const z = clamp(command.stick[1] + key("w", "s") + command.pad[2]);
  return [x * speed, y * speed, z * speed];
}
function holding() {
  return command.stickHeld || command.liftHeld || command.keys.size > 0 || command.pad.some((v) => Math.abs(v) > 0.15);
}
function beat() {
  if (!holding()) return release("released");
  send({ type: "hold", v: velocity() });
}
function press() {
  if (!controlling) return;
  if (!heartbeat) {
    beat();
    heartbeat = setInterval(beat, HEARTBEAT_MS);
  }
}
function release(reason) {
  if (heartbeat) {
    clearInterval(heartbeat);
    heartbeat = null;
    send({ type: "release", reason });
  }
}
function stopEverything(reason) {
  command.stickHeld = command.liftHeld = false;
  command.keys.clear();
  command.stick = [0, 0];
  command.lift = 0;
  centreKnobs();
  release(reason);
}
window.addEventListener("blur", () => stopEverything("window blur"));
document.addEventListener("visibilitychange", () => { if (document.hidden) stopEverything("hidden tab"); });

function centreKnobs() {
  $("knob").style.transform = "";
  $("lift-knob").style.transform = "";
  $("joystick").classList.remove("active");
  $("lift").classList.remove("active");
}
function pad(element, onMove, onHeld) {
  const move = (event) => {
    const box = element.getBoundingClientRect();
    const cx = box.left + box.width / 2;
    const cy = box.top + box.height / 2;
    const rx = Math.max(-1, Math.min(1, (event.clientX - cx) / (box.width / 2 - 22)));
    const ry = Math.max(-1, Math.min(1, (cy - event.clientY) / (box.height / 2 - 22)));
    onMove(rx, ry);
  };
  element.addEventListener("pointerdown", (event) => {
    if (!controlling) return;
    element.setPointerCapture(event.pointerId);
    element.classList.add("active");
    onHeld(true);
    move(event);
    press();
  });
  element.addEventListener("pointermove", (event) => { if (element.classList.contains("active")) move(event); });
  const up = () => {
    if (!element.classList.contains("active")) return;
    onHeld(false);
    onMove(0, 0);
    element.classList.remove("active");
    if (!holding()) release("pointer up");
  };
  element.addEventListener("pointerup", up);
  element.addEventListener("pointercancel", up);
  element.addEventListener("lostpointercapture", up);
}
pad($("joystick"), (x, y) => {
  const r = Math.hypot(x, y) > 1 ? Math.hypot(x, y) : 1;
  command.stick = [x / r, y / r];
  $("knob").style.transform = `translate(${(x / r) * 50}px, ${(-y / r) * 50}px)`;
}, (held) => { command.stickHeld = held; });
pad($("lift"), (x, y) => {
  command.lift = y;
  $("lift-knob").style.transform = `translateY(${-y * 58}px)`;
}, (held) => { command.liftHeld = held; });

const KEYS = new Set(["a", "d", "w", "s", "r", "f"]);
window.addEventListener("keydown", (event) => {
  if (event.target.tagName === "INPUT" || event.target.tagName === "SELECT") return;
  if (event.key === "Escape") return estop("Esc key");
  const key = event.key.toLowerCase();
  if (!KEYS.has(key) || !controlling) return;
  command.keys.add(key);
  press();
});
window.addEventListener("keyup", (event) => {
  command.keys.delete(event.key.toLowerCase());
  if (!holding()) release("key up");
});

// Gamepad API: left stick x / y -> x / z, right stick y -> y; any button 0 press is not needed: hold the stick.
function pollGamepad() {
  const pads = navigator.getGamepads ? [...navigator.getGamepads()].filter(Boolean) : [];
  $("pad").textContent = pads.length ? pads[0].id.slice(0, 40) : "none";
  if (pads.length && controlling) {
    const axes = pads[0].axes;
    const dead = (v) => (Math.abs(v) < 0.15 ? 0 : v);
    command.pad = [dead(axes[0] || 0), dead(-(axes[3] || 0)), dead(-(axes[1] || 0))];
    if (holding()) press();
  } else {
    command.pad = [0, 0, 0];
  }
  requestAnimationFrame(pollGamepad);
}
requestAnimationFrame(pollGamepad);

function estop(reason) {
  stopEverything("e-stop");
  if (control && control.readyState === WebSocket.OPEN) send({ type: "estop", reason });
  else post("/api/estop", { reason });
}
$("estop").addEventListener("click", () => estop("e-stop button"));
$("estop-reset").addEventListener("click", () => send({ type: "reset" }));
$("acquire").addEventListener("click", () => send({ type: "acquire", name: "operator" }));
$("leave").addEventListener("click", () => { stopEverything("left"); send({ type: "leave" }); setControlling(false); });

// ------------------------------------------------------------------------------------------ state
const series = { t: [], d0: [], d1: [], pyro: [], gas: [], f: [], tq: [] };
function connectState() {
  const socket = new WebSocket(wsUrl("/ws/state"));
  socket.onopen = () => { $("link").textContent = "live"; $("link").className = "badge ok"; };
  socket.onmessage = (event) => {
    const message = JSON.parse(event.data);
    stats.status = message.status;
    showStatus(message.status);
    for (const s of message.samples) {
      series.t.push(s.t);
      series.d0.push(s.d[0]);
      series.d1.push(s.d[1]);
      series.pyro.push(s.pyro_k);
      series.gas.push(s.gas_ppm);
      series.f.push(Math.hypot(...s.f));
      series.tq.push(Math.hypot(...s.tq));
    }
    const cut = series.t.length - 44 * 20;
    if (cut > 0) for (const key of Object.keys(series)) series[key].splice(0, cut);
    drawPlots();
    updateScene(message.poses);
  };
  socket.onclose = () => {
    $("link").textContent = "disconnected";
    $("link").className = "badge bad";
    setTimeout(connectState, 1000);
  };
}
function showStatus(status) {
  const t = status.teleop;
  const op = t.operator_m_s || [0, 0, 0];
  const cmd = t.commanded_m_s || [0, 0, 0];
  $("op-x").textContent = fmt(op[0]); $("op-y").textContent = fmt(op[1]); $("op-z").textContent = fmt(op[2]);
  $("prox-z").textContent = fmt(t.proximity_m_s);
  $("cmd-x").textContent = fmt(cmd[0]); $("cmd-y").textContent = fmt(cmd[1]); $("cmd-z").textContent = fmt(cmd[2]);
  const regions = status.sensors.regions || ["-", "-"];
  regions.forEach((r, i) => { const el = $(`region-${i}`); el.textContent = r; el.style.background = REGION_COLOURS[r]; });
  $("ranges").textContent = (status.sensors.proximity_m || []).map((d) => (d === null ? "no return" : `${fmt(d, 3)} m`)).join(" / ");
  $("estop-state").textContent = t.estop ? `E-STOP LATCHED (${t.estop_reason})` : "e-stop clear";
  $("estop-state").className = `badge ${t.estop ? "bad" : "ok"}`;
  $("estop-reset").disabled = !(t.estop && controlling);
  $("acquire").disabled = !!t.operator && !controlling;
  if (t.last_stop) $("stop-info").textContent = `last stop: ${t.last_stop.reason}, ${t.last_stop.latency_s === null ? "stopping" : `${Math.round(t.last_stop.latency_s * 1000)} ms after release`}`;
  const sun = status.sun;
  $("orbit-label").textContent = `${fmt(sun.orbit_time_s, 0)} s, ${fmt(sun.orbit_angle_deg, 1)} deg from noon, ${sun.sunlit ? "sunlit" : "eclipse"}`;
  if (document.activeElement !== $("orbit-time")) $("orbit-time").value = sun.orbit_time_s % sun.period_s;
  $("orbit-time").max = sun.period_s;
  $("lamp-on").checked = sun.lamp_on;
  $("halogen-on").checked = sun.halogen_on;
  showMission(status.mission);
  followShots(status.inspection);
}

// ------------------------------------------------------------------------------------------ plots
function plot(canvas, lines, label, unit) {
  const ctx = canvas.getContext("2d");
  const { width, height } = canvas;
  ctx.clearRect(0, 0, width, height);
  ctx.fillStyle = "#8b96a3";
  ctx.font = "11px system-ui";
  const values = lines.flatMap((l) => l.values).filter((v) => v !== null && Number.isFinite(v));
  if (!values.length) { ctx.fillText(`${label}: no reading`, 4, 12); return; }
  let lo = Math.min(...values);
  let hi = Math.max(...values);
  if (hi - lo < 1e-9) { hi += 0.5; lo -= 0.5; }
  const n = series.t.length;
  for (const line of lines) {
    ctx.strokeStyle = line.colour;
    ctx.beginPath();
    let started = false;
    line.values.forEach((v, i) => {
      if (v === null || !Number.isFinite(v)) { started = false; return; }
      const x = (i / Math.max(1, n - 1)) * width;
      const y = height - 4 - ((v - lo) / (hi - lo)) * (height - 18);
      if (started) ctx.lineTo(x, y); else ctx.moveTo(x, y);
      started = true;
    });
    ctx.stroke();
  }
  const last = lines[0].values[lines[0].values.length - 1];
  ctx.fillText(`${label}: ${fmt(last, 3)} ${unit}   [${fmt(lo, 3)} .. ${fmt(hi, 3)}], last 20 s`, 4, 12);
}
function drawPlots() {
  plot($("plot-proximity"), [{ values: series.d0, colour: "#4fc3f7" }, { values: series.d1, colour: "#f06292" }], "proximity left / right", "m");
  plot($("plot-pyrometer"), [{ values: series.pyro, colour: "#ffb74d" }], "pyrometer", "K");
  plot($("plot-gas"), [{ values: series.gas, colour: "#81c784" }], "gas (MOS)", "ppm");
  plot($("plot-ft"), [{ values: series.f, colour: "#e57373" }, { values: series.tq, colour: "#ba68c8" }], "|force| N / |torque| N m", "");
}

// ------------------------------------------------------------------------------------------ 3D scene
const three = { bodies: {}, beams: [], ready: false };
function shapeGeometry(shape) {
  const s = shape.size;
  let geometry;
  if (shape.type === "box") geometry = new THREE.BoxGeometry(2 * s[0], 2 * s[1], 2 * s[2]);
  else if (shape.type === "sphere") geometry = new THREE.SphereGeometry(s[0], 12, 8);
  else if (shape.type === "ellipsoid") { geometry = new THREE.SphereGeometry(1, 12, 8); geometry.scale(s[0], s[1], s[2]); }
  else if (shape.type === "cylinder") { geometry = new THREE.CylinderGeometry(s[0], s[0], 2 * s[1], 12); geometry.rotateX(Math.PI / 2); }
  else { geometry = new THREE.CapsuleGeometry(s[0], 2 * s[1], 4, 10); geometry.rotateX(Math.PI / 2); }
  return geometry;
}
const quat = (wxyz) => new THREE.Quaternion(wxyz[1], wxyz[2], wxyz[3], wxyz[0]);
async function buildScene() {
  const host = $("scene");
  const renderer = new THREE.WebGLRenderer({ antialias: false });
  renderer.setSize(host.clientWidth, host.clientHeight);
  host.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x0b0d10);
  const camera = new THREE.PerspectiveCamera(45, host.clientWidth / host.clientHeight, 0.05, 50);
  camera.up.set(0, 0, 1);
  camera.position.set(2.6, -3.0, 2.2);
  const controls = new OrbitControls(camera, renderer.domElement);
  controls.target.set(0.9, -0.6, 1.0);
  controls.update();
  scene.add(new THREE.HemisphereLight(0xdde6ff, 0x202020, 1.6));
  const grid = new THREE.GridHelper(6, 24, 0x2c333d, 0x20262e);
  grid.rotateX(Math.PI / 2);
  scene.add(grid);
  const geometry = await api("/api/scene");
  for (const [id, pose] of Object.entries(geometry.bodies)) {
    const group = new THREE.Group();
    group.position.set(...pose.pos);
    group.quaternion.copy(quat(pose.quat));
    scene.add(group);
    three.bodies[id] = group;
  }
  for (const shape of geometry.shapes) {
    const [r, g, b, a] = shape.rgba;
    const material = new THREE.MeshLambertMaterial({ color: new THREE.Color(r, g, b), transparent: a < 1, opacity: a });
    const mesh = new THREE.Mesh(shapeGeometry(shape), material);
    mesh.position.set(...shape.pos);
    mesh.quaternion.copy(quat(shape.quat));
    three.bodies[String(shape.body)].add(mesh);
  }
  for (let i = 0; i < 2; i++) {
    const beam = new THREE.Line(new THREE.BufferGeometry().setFromPoints([new THREE.Vector3(), new THREE.Vector3()]), new THREE.LineBasicMaterial({ color: 0x607d8b }));
    scene.add(beam);
    three.beams.push(beam);
  }
  three.lamp = new THREE.Mesh(new THREE.SphereGeometry(0.06, 12, 8), new THREE.MeshBasicMaterial({ color: 0xfff59d }));
  three.spot = new THREE.Mesh(new THREE.CircleGeometry(1, 32), new THREE.MeshBasicMaterial({ color: 0xfff59d, transparent: true, opacity: 0.12, depthWrite: false, side: THREE.DoubleSide }));
  three.ray = new THREE.Line(new THREE.BufferGeometry().setFromPoints([new THREE.Vector3(), new THREE.Vector3()]), new THREE.LineDashedMaterial({ color: 0xfff59d }));
  three.replay = new THREE.Mesh(new THREE.ConeGeometry(0.05, 0.15, 12), new THREE.MeshBasicMaterial({ color: 0x40c4ff }));
  three.replay.visible = false;
  scene.add(three.lamp, three.spot, three.ray, three.replay);
  Object.assign(three, { renderer, scene, camera, controls, ready: true });
  controls.addEventListener("change", () => renderer.render(scene, camera));
  for (const [region, colour] of Object.entries(REGION_COLOURS)) {
    const swatch = document.createElement("span");
    swatch.style.background = colour; // CSSOM, allowed by the page's CSP (inline style attributes are not)
    $("legend").append(swatch, region === "-" ? "out of range" : region);
  }
}
let lastPoses = "";
function updateScene(poses) {
  if (!three.ready || !poses) return;
  const key = JSON.stringify(poses);
  if (key === lastPoses) return; // nothing moved: spare the page's main thread (it also keeps the heartbeat)
  lastPoses = key;
  for (const [id, p] of Object.entries(poses.bodies)) {
    const group = three.bodies[id];
    if (!group) continue;
    group.position.set(p[0], p[1], p[2]);
    group.quaternion.copy(quat(p.slice(3)));
  }
  poses.beams.forEach((beam, i) => {
    const start = new THREE.Vector3(...beam.start);
    const end = start.clone().addScaledVector(new THREE.Vector3(...beam.axis), beam.length_m);
    three.beams[i].geometry.setFromPoints([start, end]);
    three.beams[i].material.color.set(REGION_COLOURS[beam.region] || "#607d8b");
  });
  const lamp = poses.lamp;
  three.lamp.position.set(...lamp.position);
  three.spot.position.set(...lamp.spot);
  three.spot.scale.setScalar(Math.max(lamp.spot_radius_m, 0.01));
  three.spot.lookAt(three.lamp.position);
  three.spot.visible = lamp.on;
  three.ray.geometry.setFromPoints([three.lamp.position.clone(), three.spot.position.clone()]);
  three.ray.computeLineDistances();
  three.renderer.render(three.scene, three.camera);
}

// ------------------------------------------------------------------------------------------ inspection at hand
let shownShot = 0;
function showShot(shot) {
  const stamp = Date.now();
  for (const name of shot.images) $(`shot-${name}`).src = q(`/api/shoot/image/${name}?t=${stamp}`);
  const s = shot.summary;
  $("shot-state").textContent = shot.kind === "reference" ? "reference taken" : s.note || `${shot.flaws.length} flaw(s); threshold ${fmt(s.threshold, 2)}, registration shift ${s.registration_xy_px ? s.registration_xy_px.map((v) => fmt(v, 2)).join(", ") : "-"} px`;
  $("shot-flaws").innerHTML = shot.flaws.length ? "<tr><th>#</th><th>row, col</th><th>area px</th><th>score</th><th>polarity</th></tr>" + shot.flaws.slice(0, 8).map((f, i) => `<tr><td>${i + 1}</td><td>${f.row}, ${f.col}</td><td>${f.area_px}</td><td>${f.score}</td><td>${f.polarity}</td></tr>`).join("") : "";
}
async function shoot(kind) {
  $("shot-state").textContent = `taking ${kind} (the live views pause)...`;
  try {
    await post(`/api/shoot/${kind}`);
    const shot = await api("/api/shoot");
    shownShot = shot.seq;
    showShot(shot);
  } catch (error) {
    $("shot-state").textContent = `failed: ${error.message}`;
  }
}
function followShots(inspection) {
  if (!inspection || inspection.seq === shownShot || inspection.seq === 0) return;
  shownShot = inspection.seq;
  api("/api/shoot").then(showShot).catch(() => {});
}
$("shoot-reference").addEventListener("click", () => shoot("reference"));
$("shoot-inspection").addEventListener("click", () => shoot("inspection"));
$("orbit-time").addEventListener("change", (e) => post("/api/sun", { orbit_time_s: Number(e.target.value) }));
$("clock-rate").addEventListener("change", (e) => post("/api/sun", { clock_rate: Number(e.target.value) }));
$("lamp-on").addEventListener("change", (e) => post("/api/lamp", { on: e.target.checked }));
$("halogen-on").addEventListener("change", (e) => post("/api/lamp", { halogen: e.target.checked }));

// ------------------------------------------------------------------------------------------ mission
let shownMissionRun = null;
$("mission-start").addEventListener("click", async () => {
  try {
    await post("/api/mission", { seed: Number($("mission-seed").value), setting: $("mission-setting").value });
    shownProvisional = -1;
  } catch (error) {
    $("mission-state").textContent = `refused: ${error.message}`;
  }
});
function showMission(m) {
  if (!m) return;
  $("mission-start").disabled = m.status === "running";
  if (m.status === "running") {
    $("mission-state").textContent = `running (seed ${m.seed}, ${m.setting}): ${m.stage} ${m.done}/${m.total}`;
    $("mission-progress").value = m.total ? m.done / m.total : 0;
    showProvisional(m.provisional || []);
  } else if (m.status === "finished") {
    $("mission-state").textContent = `finished: run ${m.run_id}, ${m.finding_count} finding(s) in ${m.elapsed_s} s`;
    $("mission-progress").value = 1;
    if (shownMissionRun !== m.run_id) {
      shownMissionRun = m.run_id;
      api(`/api/archive/runs/${m.run_id}/findings`).then((findings) => {
        $("mission-findings").innerHTML = "<tr><th>id</th><th>vista</th><th>kind</th><th>confidence</th></tr>" + findings.map((f) => `<tr class="mission-finding"><td>${f.id}</td><td>${f.vista}</td><td>${f.kind}</td><td>${fmt(f.confidence, 2)}</td></tr>`).join("");
        loadRuns();
      });
    }
  } else if (m.status === "failed") {
    $("mission-state").textContent = `failed: ${m.error}`;
  }
}

// each inspection visit's findings as it ends: provisional until the run fuses them across vistas
let shownProvisional = -1;
function showProvisional(rows) {
  if (rows.length === shownProvisional) return;
  shownProvisional = rows.length;
  $("mission-findings").innerHTML = "<tr><th>provisional</th><th>vista</th><th>kind</th><th>confidence</th></tr>" + rows.map((f) => `<tr class="mission-provisional"><td>visit</td><td>${escapeHtml(f.vista)}</td><td>${escapeHtml(f.kind)}</td><td>${fmt(f.confidence, 2)}</td></tr>`).join("");
}

// ------------------------------------------------------------------------------------------ archive
let currentRun = null;
async function loadRuns() {
  const runs = await api("/api/archive/runs");
  $("runs").innerHTML = "<tr><th>run</th><th>status</th><th>seed</th><th>findings</th><th>started</th></tr>" + runs.map((r) => `<tr data-run="${r.id}" class="${r.id === currentRun ? "selected" : ""}"><td>${r.id}</td><td>${r.status}</td><td>${r.seed ?? "-"}</td><td>${r.finding_count}</td><td>${r.started_at.slice(0, 19)}</td></tr>`).join("");
  for (const row of $("runs").querySelectorAll("tr[data-run]")) row.addEventListener("click", () => loadRun(Number(row.dataset.run)));
}
function findingRow(f) {
  const verdict = f.review ? `<span class="verdict-${f.review.verdict}">${f.review.verdict}</span>${f.review.note ? `: ${escapeHtml(f.review.note)}` : ""}` : "-";
  const crops = f.images.map((which) => `<img alt="${which}" title="${which}" src="${q(`/api/archive/findings/${f.id}/crop/${which}`)}">`).join("");
  return `<tr data-finding="${f.id}"><td>${f.id}</td><td>${f.vista}</td><td>${f.kind}</td><td>${fmt(f.confidence, 2)}</td><td>${crops}</td>
    <td class="verdict">${verdict}</td><td><button class="confirm" type="button">confirm</button><button class="reject" type="button">reject</button><button class="annotate" type="button">note</button><button class="history" type="button">sightings</button></td></tr>`;
}
function escapeHtml(text) {
  return text.replace(/[&<>"']/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" })[c]);
}
async function loadRun(runId) {
  currentRun = runId;
  $("run-title").textContent = `run ${runId}`;
  $("replay").disabled = false;
  const findings = await api(`/api/archive/runs/${runId}/findings`);
  $("findings").innerHTML = "<tr><th>id</th><th>vista</th><th>kind</th><th>conf.</th><th>crops</th><th>review</th><th></th></tr>" + findings.map(findingRow).join("");
  for (const row of $("findings").querySelectorAll("tr[data-finding]")) {
    const id = Number(row.dataset.finding);
    row.querySelector(".confirm").addEventListener("click", () => review(id, "confirmed"));
    row.querySelector(".reject").addEventListener("click", () => review(id, "rejected"));
    row.querySelector(".annotate").addEventListener("click", () => {
      const note = prompt("Note on this finding");
      if (note !== null) review(id, "note", note);
    });
    row.querySelector(".history").addEventListener("click", () => showHistory(id));
  }
  loadRuns();
}
async function review(id, verdict, note = "") {
  await post(`/api/archive/findings/${id}/review`, { verdict, note });
  if (currentRun !== null) await loadRun(currentRun);
}
async function showHistory(id) {
  const sightings = await api(`/api/archive/findings/${id}/history`);
  $("history").innerHTML = `<h2>sightings of finding ${id}'s flaw (track ${sightings[0].track_id})</h2><table class="list"><tr><th>run</th><th>seen</th><th>size m</th><th>confidence</th><th>crop</th></tr>` + sightings.map((s) => `<tr><td>${s.run_id}</td><td>${s.seen_at.slice(0, 19)}</td><td>${fmt(s.size_m, 4)}</td><td>${fmt(s.confidence, 2)}</td><td>${s.images.length ? `<img alt="${s.images[s.images.length - 1]}" src="${q(`/api/archive/findings/${s.id}/crop/${s.images[s.images.length - 1]}`)}">` : ""}</td></tr>`).join("") + "</table>";
}
$("archive-refresh").addEventListener("click", loadRuns);
$("replay").addEventListener("click", async () => {
  const replay = await api(`/api/archive/runs/${currentRun}/replay`);
  three.replay.visible = true;
  for (const [index, step] of replay.steps.entries()) {
    $("replay-state").textContent = `vista ${index + 1}/${replay.steps.length}: ${step.vista}, ${step.findings.length} finding(s)`;
    three.replay.position.set(...step.position_m);
    three.replay.lookAt(new THREE.Vector3(...step.target_m));
    three.replay.rotateX(-Math.PI / 2);
    for (const row of $("findings").querySelectorAll("tr[data-finding]")) {
      row.classList.toggle("selected", step.findings.some((f) => f.id === Number(row.dataset.finding)));
    }
    if (three.ready) three.renderer.render(three.scene, three.camera);
    await new Promise((resolve) => setTimeout(resolve, 1200));
  }
  $("replay-state").textContent = `replayed ${replay.steps.length} vista(s)`;
  three.replay.visible = false;
});

// ------------------------------------------------------------------------------------------ start
connectVideo();
connectControl();
connectState();
buildScene().catch((error) => { $("scene").textContent = `3D view unavailable: ${error.message}`; });
loadRuns();
