"use strict";
// Shared by the experiment and calibration pages: element lookup and JSON calls.
const $ = (id) => document.getElementById(id);
async function call(url, body) {
  const r = body === undefined ? await fetch(url) : await fetch(url, { method: "POST",
    headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) });
  const j = await r.json();
  if (!r.ok) throw new Error(j.error || r.statusText);
  return j;
}
