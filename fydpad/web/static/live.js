"use strict";
const $ = (id) => document.getElementById(id);
const WINDOW_S = 10;
let since = -1, settings = null, frameInfo = null;
const data = { t: [], x: [], y: [], z: [], f: [] };
const fmt = (v, d = 1) => (v === null || v === undefined || Number.isNaN(v)) ? "—" : Number(v).toFixed(d);

// One axis per quantity, each titled with its unit; the time axis too.
function mkPlot(el, series, axes, scales) {
  return new uPlot({ width: 560, height: 190, scales: { x: { time: false }, ...scales },
    series: [{ label: "t (s)" }, ...series], axes: [{ label: "time (s)" }, ...axes] },
    [[], ...series.map(() => [])], el);
}
const plotXY = mkPlot($("plot-xy"),
  [{ label: "x (mm)", stroke: "#d32", scale: "mm" }, { label: "y (mm)", stroke: "#26c", scale: "mm" }],
  [{ label: "position (mm)", scale: "mm" }], { mm: {} });
const plotZF = mkPlot($("plot-zf"),
  [{ label: "indentation (mm)", stroke: "#393", scale: "mm" }, { label: "force (N)", stroke: "#a3a", scale: "N" }],
  [{ label: "indentation (mm)", scale: "mm" }, { label: "force (N)", scale: "N", side: 1, grid: { show: false } }],
  { mm: {}, N: {} });

function addSamples(samples) {
  for (const s of samples) {
    since = Math.max(since, s[0]);
    data.t.push(s[1]); data.x.push(s[3]); data.y.push(s[4]); data.z.push(s[5]); data.f.push(s[6]);
  }
  const tEnd = data.t.length ? data.t[data.t.length - 1] : 0;
  while (data.t.length && data.t[0] < tEnd - WINDOW_S) { for (const k in data) data[k].shift(); }
  plotXY.setData([data.t, data.x, data.y]);
  plotZF.setData([data.t, data.z, data.f]);
}

// Fields the user edited and has not applied yet are not overwritten by the polling.
const dirty = new Set();
for (const id of ["roi", "threshold", "flip", "stiffness", "gain", "vib"]) {
  $(id).addEventListener("input", () => dirty.add(id));
  $(id).addEventListener("change", () => dirty.add(id));
}
function fillSettings(s, force) {
  settings = s;
  if (force) dirty.clear();
  const set = (id, v) => { if (force || !dirty.has(id)) { if ($(id).type === "checkbox") $(id).checked = v; else $(id).value = v; } };
  set("roi", s.roi_px.join(","));
  set("threshold", s.threshold);
  set("flip", s.image_flip);
  set("stiffness", s.stiffness_n_per_mm === null ? "" : s.stiffness_n_per_mm);
  set("gain", s.vibration_gain);
  set("vib", s.vibration_enabled);
}

function showStats(st) {
  const rows = ["render", "vision"].map((k) => {
    const r = st[k];
    if (!r) return `<tr><td>${k}</td><td colspan="4">—</td></tr>`;
    const j = r.jitter_ms || {};
    return `<tr id="loop-${k}"><td>${k}</td><td>${fmt(r.rate_hz)}</td><td>${fmt(r.on_time_pct, 2)}</td><td>${fmt(j.p50, 3)}</td><td>${fmt(j.p99, 3)}</td></tr>`;
  });
  $("loops").innerHTML = "<tr><th>loop</th><th>rate Hz</th><th>on time %</th><th>jitter p50 ms</th><th>jitter p99 ms</th></tr>" + rows.join("");
  const f = st.frame_to_command_ms;
  const v = st.vision || {};
  // A live camera drops frames now and then: counted and shown, never fatal.
  const cam = v.camera_read_failures === undefined ? "" :
    `; camera dropped ${v.camera_read_failures} frames (${v.camera_outages} outages)`;
  $("f2c").textContent = (f ? `frame to command p50 ${fmt(f.p50)} ms, p99 ${fmt(f.p99)} ms` : "") + cam;
}

let firstSettings = true;
async function poll() {
  try {
    const r = await fetch(`api/state?since=${since}`);
    if (r.ok) {
      const j = await r.json();
      addSamples(j.samples);
      frameInfo = j.frame;
      $("status").textContent = frameInfo ? `frame ${frameInfo.index}` : "waiting for frames";
      showStats(j.stats);
      $("link").textContent = j.link ? JSON.stringify(j.link) : "no link";
      showHold(j.operator_hold);
      const s = j.settings;
      $("render").textContent = `softness ${fmt(s.stiffness_n_per_mm, 2)} N/mm; texture ${s.texture || "none"} ` +
        `(${s.vibration_enabled ? "on" : "off"}, gain ${fmt(s.vibration_gain, 2)})` +
        (j.stimulus ? `; experiment stimulus ${j.stimulus.name} (grating ${j.stimulus.grating_mm} mm, ` +
          `${j.stimulus_rendered ? "rendered" : "shown only"})` : "") +
        (j.texture ? `; render process: model ${j.texture.model || "none"}, ${j.texture.switches} switches` : "");
      fillSettings(s, firstSettings); firstSettings = false;
    }
  } catch (e) { $("status").textContent = "station not reachable"; }
  setTimeout(poll, 100);
}

// The camera image and the readout under it: one frame's. /api/frame.jpg carries that
// frame's numbers in its X-Fydpad-Frame header; the readout is written from them when
// the image has loaded, never from the (newer) polled samples.
function showReadout(m) {
  const r = $("readout");
  r.dataset.frame = m.index;
  r.innerHTML = (m.contact
    ? `frame <span id="rframe">${m.index}</span>: contact x <span id="x">${fmt(m.x_mm)}</span> mm  y <span id="y">${fmt(m.y_mm)}</span> mm`
    : `frame <span id="rframe">${m.index}</span>: no contact <span id="x" hidden></span><span id="y" hidden></span>`) +
    `  z ${fmt(m.indentation_mm)} mm  F ${fmt(m.force_n, 2)} N`;
}
// One request at a time, at most 10 per second; hidden until a frame has loaded (no
// broken image before the station has one).
async function nextFrame() {
  const img = $("frame"), t0 = performance.now();
  const again = (ms) => setTimeout(nextFrame, Math.max(0, ms - (performance.now() - t0)));
  let r;
  try { r = await fetch(`api/frame.jpg?n=${Date.now()}`, { cache: "no-store" }); }
  catch (e) { again(500); return; }
  if (r.status !== 200) { again(500); return; }
  const meta = JSON.parse(r.headers.get("X-Fydpad-Frame"));
  const url = URL.createObjectURL(await r.blob());
  // Decoded off screen first, the image and its readout then swap in one turn of script
  // (an image already in the document's list of available images shows at once).
  const pre = new Image();
  pre.src = url;
  try { await pre.decode(); } catch (e) { URL.revokeObjectURL(url); again(500); return; }
  const old = img.dataset.url;
  img.src = url;
  img.dataset.url = url; img.dataset.frame = meta.index;
  showReadout(meta);
  img.hidden = false;
  if (old) URL.revokeObjectURL(old);
  again(100);
}

// ROI by dragging on the image (image pixels = the flipped frame's pixels).
let dragStart = null;
function imgPos(ev) {
  const r = $("frame").getBoundingClientRect();
  const w = frameInfo ? frameInfo.width : 640, h = frameInfo ? frameInfo.height : 480;
  return [Math.round((ev.clientX - r.left) * w / r.width), Math.round((ev.clientY - r.top) * h / r.height), r, w, h];
}
$("view").addEventListener("mousedown", (ev) => { dragStart = imgPos(ev); ev.preventDefault(); });
$("view").addEventListener("mousemove", (ev) => {
  if (!dragStart) return;
  const p = imgPos(ev), sx = p[2].width / p[3], d = $("drag");
  d.style.display = "block";
  d.style.left = Math.min(dragStart[0], p[0]) * sx + "px"; d.style.top = Math.min(dragStart[1], p[1]) * sx + "px";
  d.style.width = Math.abs(p[0] - dragStart[0]) * sx + "px"; d.style.height = Math.abs(p[1] - dragStart[1]) * sx + "px";
});
window.addEventListener("mouseup", (ev) => {
  if (!dragStart) return;
  const p = imgPos(ev);
  const x = Math.max(0, Math.min(dragStart[0], p[0])), y = Math.max(0, Math.min(dragStart[1], p[1]));
  const w = Math.min(p[3], Math.max(dragStart[0], p[0])) - x, h = Math.min(p[4], Math.max(dragStart[1], p[1])) - y;
  dragStart = null; $("drag").style.display = "none";
  if (w > 8 && h > 8) { $("roi").value = [x, y, w, h].join(","); apply(); }
});

function msg(text, err) { $("msg").textContent = text; $("msg").className = err ? "msg err" : "msg"; }
async function post(url, body) {
  const r = await fetch(url, { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body || {}) });
  const j = await r.json();
  if (!r.ok) throw new Error(j.error || r.statusText);
  return j;
}
async function apply() {
  const body = { roi_px: $("roi").value.split(",").map(Number), threshold: Number($("threshold").value),
    image_flip: $("flip").value, vibration_gain: Number($("gain").value), vibration_enabled: $("vib").checked };
  if ($("stiffness").value !== "") body.stiffness_n_per_mm = Number($("stiffness").value);
  try { const j = await post("api/settings", body); fillSettings(j.settings, true); msg("applied"); }
  catch (e) { msg(e.message, true); }
}
// The operator hold: the robot holds still and the vibration is silenced until released.
function showHold(held) {
  const b = $("hold");
  b.textContent = held ? "Release robot" : "Hold robot";
  b.classList.toggle("held", !!held);
  b.dataset.held = held ? "1" : "0";
}
$("hold").onclick = async () => {
  try { const j = await post("api/hold", { on: $("hold").dataset.held !== "1" }); showHold(j.operator_hold); }
  catch (e) { msg(e.message, true); }
};
$("apply").onclick = apply;
$("save").onclick = async () => {
  try { await apply(); const j = await post("api/save"); msg(j.message); } catch (e) { msg(e.message, true); }
};
$("calib").onclick = () => { window.location.href = "calibrate"; };

poll(); nextFrame();
