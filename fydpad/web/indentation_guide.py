"""The web view's guide through the indentation calibration protocol
(``fydpad.indentation_protocol``), one step at a time: what to do, and for each
recording a map of the workspace with its press points numbered in order and labelled
with their depth. Served at ``/indentation-guide``; a static page built from the same
steps ``fydpad calibrate indentation --protocol`` prints.
"""

from __future__ import annotations

import html

from aiohttp import web

from fydpad.indentation_protocol import DEPTHS_MM, Press, duration_s, steps

#: Point colour per depth, shallow to deep.
_COLOURS = ("#7fc97f", "#386cb0", "#f0a030", "#d01c1c")


def workspace_svg(presses: tuple[Press, ...], workspace_mm: tuple[float, float] = (100.0, 70.0),
                  px_per_mm: float = 5.0) -> str:
    """The workspace seen from above (x right, y away from the user) with the presses."""
    w, h = workspace_mm
    sx = lambda x: (x + w / 2) * px_per_mm  # noqa: E731
    sy = lambda y: (h / 2 - y) * px_per_mm  # noqa: E731
    parts = [f'<svg class="ws" width="{w * px_per_mm:.0f}" height="{h * px_per_mm + 18:.0f}" '
             f'viewBox="0 0 {w * px_per_mm:.0f} {h * px_per_mm + 18:.0f}" role="img" '
             f'aria-label="press points">',
             f'<rect x="0" y="0" width="{w * px_per_mm:.0f}" height="{h * px_per_mm:.0f}" '
             'fill="#f4f1ea" stroke="#888"/>',
             f'<text x="4" y="{h * px_per_mm + 14:.0f}" font-size="12">user side '
             f'(workspace {w:.0f} x {h:.0f} mm)</text>']
    for p in presses:
        colour = _COLOURS[DEPTHS_MM.index(p.depth_mm) % len(_COLOURS)]
        r = 6 + p.depth_mm / 5
        parts.append(
            f'<g class="press" data-depth="{p.depth_mm:g}"><circle cx="{sx(p.x_mm):.1f}" '
            f'cy="{sy(p.y_mm):.1f}" r="{r:.1f}" fill="{colour}" fill-opacity="0.8"/>'
            f'<text x="{sx(p.x_mm):.1f}" y="{sy(p.y_mm) + 4:.1f}" font-size="11" '
            f'text-anchor="middle" fill="#fff">{p.number}</text>'
            f'<text x="{sx(p.x_mm):.1f}" y="{sy(p.y_mm) + r + 11:.1f}" font-size="10" '
            f'text-anchor="middle">{p.depth_mm:g} mm</text></g>')
    parts.append("</svg>")
    return "".join(parts)


def guide_html() -> str:
    """The whole guide: every step a section, one shown at a time (Back / Next)."""
    sections = []
    all_steps = steps()
    for k, s in enumerate(all_steps, 1):
        body = f"<p>{html.escape(s.text)}</p>"
        if s.presses:
            rows = "".join(f"<tr><td>{p.number}</td><td>{p.x_mm:+.0f}</td><td>{p.y_mm:+.0f}"
                           f"</td><td>{p.depth_mm:g}</td></tr>" for p in s.presses)
            body += (workspace_svg(s.presses) + "<table class='presses'><tr><th>#</th>"
                     "<th>x mm</th><th>y mm</th><th>depth mm</th></tr>" + rows + "</table>")
        sections.append(f'<section class="card step" id="step-{k}" data-step="{k}"'
                        f'{"" if k == 1 else " hidden"}><h2>Step {k} of {len(all_steps)}: '
                        f"{html.escape(s.title)}</h2>{body}</section>")
    legend = ", ".join(f'<span style="color:{c}">&#9679;</span> {d:g} mm'
                       for c, d in zip(_COLOURS, DEPTHS_MM, strict=True))
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>fydpad: indentation calibration guide</title>
<link rel="stylesheet" href="static/style.css"></head>
<body>
<header><b>Indentation calibration</b><span class="readout">{duration_s():.0f} s of
recording in 3 takes (about 2 minutes); depths: {legend}</span><a href="./">station</a></header>
<main style="display:block">
{''.join(sections)}
<div class="card"><button id="back">Back</button> <button id="next">Next</button>
<span id="where" class="readout"></span></div>
</main>
<script>
const steps = [...document.querySelectorAll("section.step")];
let at = 0;
function show(k) {{
  at = Math.max(0, Math.min(steps.length - 1, k));
  steps.forEach((s, i) => {{ s.hidden = i !== at; }});
  document.getElementById("where").textContent = `step ${{at + 1}} of ${{steps.length}}`;
  document.getElementById("back").disabled = at === 0;
  document.getElementById("next").disabled = at === steps.length - 1;
}}
document.getElementById("back").onclick = () => show(at - 1);
document.getElementById("next").onclick = () => show(at + 1);
show(0);
</script>
</body></html>
"""


async def indentation_guide(request: web.Request) -> web.Response:
    return web.Response(text=guide_html(), content_type="text/html")
