"""The web view's flows in a real browser (Debian's Chromium, Playwright):

- the workspace calibration through the page against the synthetic pad pressing the 9
  marked points (``fydpad run --synthetic presses``), checked against the pad's true
  image-to-workspace mapping;
- an experiment whose stimuli switch the texture model the render process renders
  (``--motors sim``: the render process reports the model it renders);
- a friction-gain staircase session through the page, its b applied live to the friction
  model the station renders, its log resumable.

Screenshots go to the test's tmp dir and ``out/web-artifacts/`` (git-ignored).
"""

from __future__ import annotations

import json
import math
import time
import urllib.request

import numpy as np
import pytest

from fydpad.config import StationConfig, load_config, save_config
from tests.conftest import write_blob_recording
from tests.web.test_browser import browser, page, start_station, stop_station  # noqa: F401
from vision.calibration import apply_homography
from vision.mapping import flip_point, roi_to_workspace

FPS = 15.0


def _get(base: str, path: str) -> dict:
    op = urllib.request.build_opener(urllib.request.ProxyHandler({}))
    return json.loads(op.open(f"{base}{path}", timeout=10).read())


def _wait_state(base: str, pred, what: str, timeout_s: float = 20.0) -> dict:
    """The station's state once ``pred(state)`` holds (the render process reports what it
    renders once a second)."""
    deadline = time.monotonic() + timeout_s
    while True:
        state = _get(base, "/api/state?since=999999999999")
        if pred(state):
            return state
        if time.monotonic() > deadline:
            pytest.fail(f"{what}: not seen; last state: texture {state.get('texture')}")
        time.sleep(0.2)


@pytest.fixture(scope="module")
def pressing_station(tmp_path_factory):
    """The synthetic pad pressing the calibration points, round after round (16 s)."""
    tmp = tmp_path_factory.mktemp("presses")
    config = tmp / "pad.toml"
    save_config(StationConfig(), config)
    proc, base, _, err = start_station(
        ["--synthetic", "presses", "--config", str(config), "--web", "127.0.0.1:0",
         "--duration", "60", "--no-realtime"], tmp)
    yield {"base": base, "config": config}
    stop_station(proc, err)


def test_workspace_calibration_through_the_page(pressing_station, page):  # noqa: F811
    page.goto(f"{pressing_station['base']}/calibrate")
    page.click("#cal-start")
    # The collector waits for clear fabric, then takes the presses in order (at most
    # two rounds of the pad's presses: ~32 s).
    page.wait_for_function("() => document.getElementById('cal-state').textContent"
                           ".startsWith('press point 2')", timeout=90000)
    page.shot("pressing")
    page.wait_for_selector("#cal-fitcard:not([hidden])", timeout=90000)
    page.shot("fitted")
    residuals = [float(page.locator(f"#res-{i}").text_content()) for i in range(1, 10)]
    assert max(residuals) == pytest.approx(float(page.locator("#cal-worst").text_content()),
                                           abs=1e-3)
    page.click("#cal-save")
    page.wait_for_function("() => document.getElementById('cal-msg').textContent"
                           ".startsWith('applied and saved')")
    cam = load_config(pressing_station["config"]).camera
    h = cam.workspace_homography
    assert h is not None and h.rms_mm < 0.3
    # Ground truth: the synthetic pad renders the workspace linearly through the ROI,
    # then flips the frame; the fitted homography must give that mapping back over the
    # inner 80 % of the workspace (the CLI's target: 0.3 mm; measured 0.15 mm max).
    roi, ws = cam.roi_px, cam.workspace_mm
    us, vs = np.meshgrid(roi[0] + roi[2] * np.linspace(0.1, 0.9, 9),
                         roi[1] + roi[3] * np.linspace(0.1, 0.9, 7))
    x, y = roi_to_workspace(us.ravel(), vs.ravel(), roi, ws)
    raw = np.array([flip_point(u, v, cam.image_flip, (640, 480))
                    for u, v in zip(us.ravel(), vs.ravel(), strict=True)])
    got = apply_homography(h.h, raw)
    assert np.hypot(got[:, 0] - x, got[:, 1] - y).max() < 0.3


@pytest.fixture(scope="module")
def render_station(tmp_path_factory):
    """A replayed blob circling, the simulated motors, a friction model as --texture and
    the experiment's grating models loaded by the render process."""
    tmp = tmp_path_factory.mktemp("render")
    n = int(60 * FPS)
    write_blob_recording(tmp / "rec", [(30 * math.cos(2 * math.pi * k / 90),
                                        20 * math.sin(2 * math.pi * k / 90))
                                       for k in range(n)], fps=FPS)
    friction = tmp / "friction.json"
    friction.write_text(json.dumps({
        "format": "fydpad-texture-model", "kind": "friction", "format_version": 1,
        "mu": list(0.5 + 0.2 * np.sin(np.linspace(0, 2 * np.pi, 200, endpoint=False))),
        "dx_mm": 0.05, "x0_mm": 0.0}))
    proc, base, _, err = start_station(
        ["--replay", str(tmp / "rec"), "--motors", "sim", "--texture", str(friction),
         "--web", "127.0.0.1:0", "--web-results", str(tmp / "results"), "--duration", "60",
         "--no-realtime"], tmp)
    yield {"base": base, "results": tmp / "results", "friction": str(friction)}
    stop_station(proc, err)


def test_experiment_stimulus_switches_the_rendered_texture(render_station, page):  # noqa: F811
    base = render_station["base"]
    page.goto(f"{base}/experiment")
    page.fill("#participant", "T01")
    page.fill("#repeats", "1")
    page.fill("#seed", "7")
    page.click("#start")
    seen = set()
    for k in range(1, 5):
        page.wait_for_function(f"() => document.getElementById('trial').textContent"
                               f".startsWith('trial {k} of 4')")
        desc = page.locator("#currentdesc").text_content()
        model = desc.split("texture model ")[1]
        assert model.startswith("grating:") and model.endswith(".json")
        if k <= 2:  # the render process reports the model it renders
            state = _wait_state(base, lambda j, m=model: (j["texture"] or {}).get("model") == m,
                                f"trial {k}: the render process rendering {model}")
            assert state["stimulus_rendered"] and state["texture"]["kind"] == "grating"
            seen.add(model)
        if k == 2:
            page.shot("stimulus")
        page.click(f"#answer-{page.locator('#current').text_content()}")
    page.wait_for_selector("#donecard:not([hidden])")
    assert page.locator("#average").text_content() == "100.0 %"
    # Session complete: the texture is off in the render process.
    _wait_state(base, lambda j: (j["texture"] or {}).get("index") == -1,
                "the texture off after the session")
    plan = json.loads((render_station["results"] / "T01.json").read_text())
    assert {s["texture"] for s in plan["stimuli"]} >= seen


def test_staircase_session_through_the_page(render_station, page):  # noqa: F811
    base = render_station["base"]
    page.goto(f"{base}/experiment")
    # The page names the model b goes to: the station's --texture, a friction model.
    page.wait_for_function("() => document.getElementById('st-model').textContent"
                           f" === {json.dumps(render_station['friction'])}")
    page.fill("#st-participant", "S01")
    page.click("#st-start")
    page.wait_for_selector("#st-trialcard:not([hidden])")
    answers = ["real", "real", "virtual", "virtual", "real"]
    for k, a in enumerate(answers, start=1):
        page.wait_for_function(f"() => document.getElementById('st-trial').textContent "
                               f"=== 'trial {k}'")
        page.click(f"#st-{a}")
    page.wait_for_function("() => document.getElementById('st-trial').textContent "
                           "=== 'trial 6'")
    assert page.locator("#st-b").text_content() == "410"
    # The render process applies b to the friction model it renders.
    state = _wait_state(base, lambda j: (j["texture"] or {}).get("friction_b_v") == 410,
                        "b = 410 in the rendered friction model")
    assert state["texture"]["model"] == render_station["friction"]
    page.shot("staircase")
    # A reload resumes from the server; the rest of the answers end it.
    page.reload()
    page.wait_for_function("() => document.getElementById('st-trial').textContent "
                           "=== 'trial 6'")
    for k, a in enumerate(["virtual", "real", "virtual", "real"], start=6):
        page.wait_for_function(f"() => document.getElementById('st-trial').textContent "
                               f"=== 'trial {k}'")
        page.click(f"#st-{a}")
    page.wait_for_selector("#st-done:not([hidden])")
    page.shot("staircase-done")
    # Reversals at 420, 400, 410, 400, 410, 400: the mean of the 3rd-6th.
    assert page.locator("#st-result").text_content() == "405"
    log = (render_station["results"] / "staircase" / "S01.csv").read_text().splitlines()
    assert log[0] == "trial,b,answer,reversal" and len(log) == 10
    assert log[3] == "3,420,virtual,1"
