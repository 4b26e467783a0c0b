"use strict";
// The friction-gain staircase: the server keeps the state and the log (api/staircase).
let stairs = null;
function stMsg(text, err) { $("st-msg").textContent = text; $("st-msg").className = err ? "msg err" : "msg"; }
function stShow(s) {
  stairs = s;
  if (!s) return;
  $("st-participant").value = s.participant;
  $("st-start-b").value = s.start; $("st-step").value = s.step;
  $("st-trialcard").hidden = s.done; $("st-done").hidden = !s.done;
  $("st-trial").textContent = `trial ${s.trial}`;
  $("st-b").textContent = String(s.b);
  $("st-reversals").textContent = s.reversals.length
    ? `${s.reversals.join(", ")} (${s.reversals.length} of ${s.needed_reversals})` : `none yet (0 of ${s.needed_reversals})`;
  if (s.done) $("st-result").textContent = String(s.result);
  $("st-log").textContent = `log ${s.log}: ${s.history.length} answers`;
}
async function stAnswer(rougher) {
  try { stShow((await call("api/staircase/answer", { rougher, trial: stairs.trial })).staircase); stMsg(""); }
  catch (e) { stMsg(e.message, true); }
}
$("st-real").onclick = () => stAnswer("real");
$("st-virtual").onclick = () => stAnswer("virtual");
$("st-start").onclick = async () => {
  try {
    const j = await call("api/staircase/start", { participant: $("st-participant").value,
      start: Number($("st-start-b").value), step: Number($("st-step").value) });
    stShow(j.staircase); stMsg(`staircase of ${j.staircase.participant}, ${j.staircase.history.length} answers so far`);
  } catch (e) { stMsg(e.message, true); }
};
call("api/staircase").then((j) => {
  stShow(j.staircase);
  // No friction model rendered: say so, and no session that would change nothing.
  if (j.unavailable) { stMsg(j.unavailable, true); $("st-start").disabled = true; }
  $("st-model").textContent = j.friction_model || "none";
}).catch(() => {});
