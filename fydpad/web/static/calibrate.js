"use strict";
// The workspace calibration: the server collects one press per marked point from the live
// tracker (api/calibration) and fits the homography; this page shows the points and the fit.
let cal = null, workspace = [100, 70];
function msg(text, err) { $("cal-msg").textContent = text; $("cal-msg").className = err ? "msg err" : "msg"; }
function drawPoints(c) {
  const svg = $("ws"), W = 520, H = 380, sx = W / workspace[0], sy = H / workspace[1];
  let h = `<rect x="0" y="0" width="${W}" height="${H}" fill="#f4f4f4" stroke="#888"/>`;
  (c ? c.targets_mm : []).forEach(([x, y], i) => {
    const u = (x + workspace[0] / 2) * sx, v = (workspace[1] / 2 - y) * sy;
    const done = i < c.next, cur = i === c.next && c.state === "press";
    const fill = done ? "#2a2" : cur ? "#d22" : "#bbb";
    h += `<circle id="pt-${i + 1}" cx="${u}" cy="${v}" r="${cur ? 14 : 9}" fill="${fill}"/>` +
      `<text x="${u + 16}" y="${v + 5}" font-size="14">${i + 1}</text>`;
  });
  svg.innerHTML = h;
}
function show(c) {
  cal = c;
  drawPoints(c);
  if (!c) { $("cal-state").textContent = "not started"; $("cal-fitcard").hidden = true; return; }
  const n = c.targets_mm.length;
  if (c.state === "clear") {
    $("cal-state").textContent = "keep the fabric clear";
    $("cal-hint").textContent = `lift the finger: the first press counts after ${c.clear_s} s without contact`;
  } else if (c.state === "press") {
    const [x, y] = c.targets_mm[c.next];
    $("cal-state").textContent = `press point ${c.next + 1} of ${n}`;
    $("cal-hint").textContent = `at x ${x.toFixed(1)} mm, y ${y.toFixed(1)} mm: hold still at least ${c.min_hold_s} s, then lift` +
      (c.pressing ? " (pressing…)" : "") + (c.short_presses ? `; ${c.short_presses} press(es) too short, ignored` : "");
  } else {
    $("cal-state").textContent = `all ${n} points pressed`;
    $("cal-hint").textContent = "";
  }
  const f = c.fit;
  $("cal-fitcard").hidden = !f;
  if (f && f.error) { msg(f.error, true); $("cal-fitcard").hidden = true; }
  else if (f) {
    $("cal-rms").textContent = f.rms_mm.toFixed(3);
    $("cal-worst").textContent = Math.max(...f.residual_mm).toFixed(3);
    let h = "<tr><th>point</th><th>x mm</th><th>y mm</th><th>press u px</th><th>press v px</th><th>residual mm</th></tr>";
    f.residual_mm.forEach((r, i) => {
      h += `<tr><td>${i + 1}</td><td>${c.targets_mm[i][0]}</td><td>${c.targets_mm[i][1]}</td>` +
        `<td>${c.presses_px[i][0]}</td><td>${c.presses_px[i][1]}</td><td id="res-${i + 1}">${r.toFixed(3)}</td></tr>`;
    });
    $("cal-residuals").innerHTML = h;
  }
}
async function poll() {
  try {
    const st = await call("api/state?since=999999999999");
    workspace = st.settings.workspace_mm;
    show((await call("api/calibration")).calibration);
  } catch (e) { msg(e.message, true); }
  setTimeout(poll, 200);
}
function nextFrame() {
  const img = $("frame"), t0 = performance.now();
  img.onload = () => setTimeout(nextFrame, Math.max(0, 200 - (performance.now() - t0)));
  img.onerror = () => setTimeout(nextFrame, 500);
  img.src = `api/frame.jpg?n=${Date.now()}`;
}
$("cal-start").onclick = async () => {
  try {
    show((await call("api/calibration/start", { points: Number($("cal-points").value),
      min_hold_s: Number($("cal-hold").value) })).calibration);
    msg("started");
  } catch (e) { msg(e.message, true); }
};
$("cal-cancel").onclick = async () => { show((await call("api/calibration/cancel", {})).calibration); msg("cancelled"); };
$("cal-save").onclick = async () => {
  try { msg((await call("api/calibration/save", {})).message); } catch (e) { msg(e.message, true); }
};
poll(); nextFrame();
