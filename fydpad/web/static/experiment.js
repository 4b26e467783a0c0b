"use strict";
let session = null;
function msg(text, err) { $("msg").textContent = text; $("msg").className = err ? "msg err" : "msg"; }
function pct(v) { return v === null ? "—" : (100 * v).toFixed(1) + " %"; }
function show(s) {
  session = s;
  if (!s) return;
  $("participant").value = s.participant;
  $("trialcard").hidden = s.done; $("donecard").hidden = !s.done;
  if (!s.done) {
    $("trial").textContent = `trial ${s.trial} of ${s.total}`;
    $("current").textContent = s.current.name;
    $("currentdesc").textContent = `${s.current.description}: ${s.current.stiffness_n_per_mm} N/mm, grating ${s.current.grating_mm} mm` +
      `; texture model ${s.current.texture || "none"}`;
  } else {
    $("donemsg").textContent = `${s.total} answers written to ${s.csv}`;
  }
  $("answers").innerHTML = "";
  for (const n of s.names) {
    const b = document.createElement("button");
    b.textContent = n; b.id = "answer-" + n; b.disabled = s.done;
    b.onclick = async () => {
      try { show((await call("api/experiment/answer", { answer: n, trial: s.trial })).session); msg(""); }
      catch (e) { msg(e.message, true); }
    };
    $("answers").appendChild(b);
  }
  const c = s.confusion;
  let h = "<table id='confusion'><tr><th></th>" + c.names.map((n) => `<th>${n}</th>`).join("") + "<th>Relative accuracy</th></tr>";
  c.counts.forEach((row, i) => {
    h += `<tr><th>${c.names[i].replace("SS", "SH")}</th>` + row.map((v, j) => `<td class="${i === j ? "diag" : ""}">${v}</td>`).join("") +
      `<td id="acc-${c.names[i]}">${pct(c.per_specimen_accuracy[i])}</td></tr>`;
  });
  h += `</table><p>average <b id="average">${pct(c.accuracy)}</b> (${c.answers} answers), chance ${pct(c.chance)}</p>`;
  $("table").innerHTML = h;
  $("plot").src = `api/experiment/plot.png?n=${c.answers}`;
}
$("start").onclick = async () => {
  try {
    const j = await call("api/experiment/start", { participant: $("participant").value,
      repeats: Number($("repeats").value), seed: $("seed").value });
    show(j.session); msg(`session of ${j.session.participant}, seed ${j.session.seed}`);
  } catch (e) { msg(e.message, true); }
};
call("api/experiment").then((j) => show(j.session)).catch(() => {});
