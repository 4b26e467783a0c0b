"""The camera image and the readout under it show one frame, in headless Chromium.

A real station replays (in real time, looping) a dark blob circling the workspace; the
page's image and its readout are sampled in one turn of script over many frames. The
blob's centroid is measured in the pixels the page displays (the image drawn to a
canvas) and compared with the readout's x, y mapped to pixels: the blob moves 8-12 px a
frame, so a readout one frame off the image misses by more than the 3 px allowed.
"""

from __future__ import annotations

import math

import pytest

from fydpad.config import StationConfig, save_config
from tests.conftest import write_blob_recording
from tests.web.test_browser import (  # noqa: F401  (fixtures)
    ARGS,
    CHROMIUM,
    TIMEOUT_MS,
    browser,
    start_station,
    stop_station,
)
from vision.mapping import workspace_to_roi

FPS = 15.0
FRAMES = 90  # one turn of the circle: 6 s, replayed in a loop
ROI_PX = (24, 22, 592, 414)
WORKSPACE_MM = (100.0, 70.0)
TOLERANCE_PX = 3.0

#: In one turn of script: the displayed image's frame, the readout's frame and values,
#: and the dark blob's centroid in the displayed pixels; for `n` distinct frames.
SAMPLE_JS = """async (n) => {
  const seen = new Map(), t0 = performance.now();
  const c = document.createElement("canvas"); c.width = 640; c.height = 480;
  const g = c.getContext("2d", { willReadFrequently: true });
  while (seen.size < n && performance.now() - t0 < 120000) {
    const img = document.getElementById("frame"), r = document.getElementById("readout");
    const x = document.getElementById("x"), y = document.getElementById("y");
    const key = img.dataset.frame;
    if (key && !seen.has(key) && img.complete && img.naturalWidth === 640 && x && y) {
      g.drawImage(img, 0, 0);
      const d = g.getImageData(0, 0, 640, 480).data;
      let su = 0, sv = 0, k = 0;
      for (let i = 0; i < d.length; i += 4) {
        if (d[i] < 110 && d[i + 1] < 110 && d[i + 2] < 110) {
          const p = i / 4; su += p % 640; sv += Math.floor(p / 640); k++;
        }
      }
      seen.set(key, { image: Number(key), readout: Number(r.dataset.frame),
        shown: document.getElementById("rframe").textContent,
        x: x.textContent, y: y.textContent, u: su / k, v: sv / k, dark: k });
    }
    await new Promise((res) => setTimeout(res, 25));
  }
  return [...seen.values()];
}"""


@pytest.fixture(scope="module")
def station(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("sync")
    positions = [(30 * math.cos(2 * math.pi * k / FRAMES), 20 * math.sin(2 * math.pi * k / FRAMES))
                 for k in range(FRAMES)]
    write_blob_recording(tmp / "rec", positions, fps=FPS)
    config = tmp / "pad.toml"
    save_config(StationConfig(), config)
    proc, base, _token, err = start_station(
        ["--replay", str(tmp / "rec"), "--loop", "--config", str(config), "--web", "0",
         "--web-results", str(tmp / "results"), "--duration", "300"], tmp)
    yield base
    stop_station(proc, err)


def test_overlay_and_readout_show_one_frame(station, browser):  # noqa: F811
    ctx = browser.new_context(viewport={"width": 1280, "height": 1000})
    page = ctx.new_page()
    page.set_default_timeout(TIMEOUT_MS)
    try:
        page.goto(f"{station}/")
        page.wait_for_function("() => document.getElementById('frame').dataset.frame")
        samples = page.evaluate(SAMPLE_JS, 40)
    finally:
        ctx.close()
    assert len(samples) == 40, f"only {len(samples)} distinct frames were displayed"
    # Many different frames of the moving finger were compared (not one held image).
    assert len({s["image"] for s in samples}) == 40
    for s in samples:
        assert s["readout"] == s["image"] and int(s["shown"]) == s["image"], s
        assert s["dark"] > 200, f"no blob in the displayed frame {s['image']}: {s}"
        u, v = workspace_to_roi(float(s["x"]), float(s["y"]), ROI_PX, WORKSPACE_MM)
        # The blob spans [round(u) - 12, round(u) + 12): its pixel centroid is u - 0.5.
        miss_px = math.hypot(s["u"] + 0.5 - float(u), s["v"] + 0.5 - float(v))
        assert miss_px < TOLERANCE_PX, (
            f"frame {s['image']}: the readout x {s['x']} y {s['y']} mm is {miss_px:.1f} px "
            f"from the blob in the image")
    # The finger moved across the samples: a frame's readout could not match another's.
    us = [s["u"] for s in samples]
    assert max(us) - min(us) > 100
