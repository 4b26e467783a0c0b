"""The web view in a real browser (Debian's Chromium driven by Playwright) against a real
station (`fydpad run --replay ... --web`) replaying a small recording of a moving blob.

Screenshots go to the test's tmp dir and are copied to ``out/web-artifacts/``.
"""

from __future__ import annotations

import math
import re
import shutil
import signal
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from fydpad.config import StationConfig, load_config, save_config
from tests.conftest import REPO, write_blob_recording

CHROMIUM = Path("/usr/bin/chromium")
pytestmark = pytest.mark.skipif(not CHROMIUM.exists(),
                                reason="no /usr/bin/chromium (apt-get install chromium)")
playwright_sync = pytest.importorskip("playwright.sync_api",
                                      reason="no playwright (pip install playwright)")

ARGS = ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run", "--no-proxy-server"]
ARTIFACTS = REPO / "out" / "web-artifacts"
TIMEOUT_MS = 15000
FPS = 15.0
SECONDS = 60  # the station replays this long (the tests stop it earlier)


def _opener():
    return urllib.request.build_opener(urllib.request.ProxyHandler({}))


def start_station(args: list[str], cwd: Path):
    """``fydpad run ARGS`` in a subprocess; returns (process, base URL, token, stderr file)
    once its web view is up (180 s is a hang guard: a loaded machine starts it slowly)."""
    err = (cwd / "station.err").open("w+")
    proc = subprocess.Popen([sys.executable, "-m", "fydpad.cli", "run", *args], cwd=cwd,
                            stdout=subprocess.DEVNULL, stderr=err)
    url = None
    deadline = time.monotonic() + 180
    while url is None and time.monotonic() < deadline and proc.poll() is None:
        err.seek(0)
        m = re.search(r"web view: (\S+)", err.read())
        url = m.group(1) if m else None
        time.sleep(0.1)
    if url is None:
        proc.kill()
        err.seek(0)
        pytest.fail(f"the station did not start its web view: {err.read()}")
    base, _, token = url.partition("/?token=")
    base = base.rstrip("/").replace("0.0.0.0", "127.0.0.1")
    return proc, base, token, err


def stop_station(proc, err) -> None:
    """Ctrl-C: the station's safe stop, which also ends its render process (SIGTERM would
    leave the render process orphaned)."""
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(timeout=5)
    err.close()


@pytest.fixture(scope="module")
def station(tmp_path_factory):
    """A station replaying a blob circling the workspace, its web view on 0.0.0.0 (token)."""
    tmp = tmp_path_factory.mktemp("station")
    n = int(SECONDS * FPS)
    positions = [(30 * math.cos(2 * math.pi * k / 90), 20 * math.sin(2 * math.pi * k / 90))
                 for k in range(n)]
    write_blob_recording(tmp / "rec", positions, fps=FPS)
    config = tmp / "pad.toml"
    save_config(StationConfig(), config)
    proc, base, token, err = start_station(
        ["--replay", str(tmp / "rec"), "--config", str(config), "--web", "0.0.0.0:0",
         "--web-results", str(tmp / "results"), "--duration", str(SECONDS), "--no-realtime",
         "--stats", str(tmp / "stats.json")], tmp)
    yield {"base": base, "token": token, "config": config, "results": tmp / "results",
           "proc": proc}
    stop_station(proc, err)


@pytest.fixture(scope="module")
def browser():
    with playwright_sync.sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=str(CHROMIUM), args=ARGS, timeout=TIMEOUT_MS)
        yield b
        b.close()


@pytest.fixture
def page(browser, tmp_path, request):
    ctx = browser.new_context(viewport={"width": 1280, "height": 1000})
    pg = ctx.new_page()
    pg.set_default_timeout(TIMEOUT_MS)
    pg.shots = []  # type: ignore[attr-defined]

    def shot(name):
        path = tmp_path / f"{request.node.name}-{name}.png"
        pg.screenshot(path=str(path), full_page=True)
        ARTIFACTS.mkdir(parents=True, exist_ok=True)
        shutil.copy(path, ARTIFACTS / path.name)

    pg.shot = shot  # type: ignore[attr-defined]
    yield pg
    ctx.close()


def test_token_required_off_loopback(station):
    assert station["token"], "a non-loopback address must get a token"
    with pytest.raises(urllib.error.HTTPError) as exc:
        _opener().open(f"{station['base']}/api/state", timeout=10)
    assert exc.value.code == 401
    with pytest.raises(urllib.error.HTTPError) as exc:
        _opener().open(f"{station['base']}/api/state?token=wrong", timeout=10)
    assert exc.value.code == 401
    with _opener().open(f"{station['base']}/api/state?token={station['token']}",
                        timeout=10) as r:
        assert r.status == 200


def test_bad_settings_refused(station):
    import json

    req = urllib.request.Request(
        f"{station['base']}/api/settings?token={station['token']}",
        data=json.dumps({"roi_px": [600, 400, 200, 200]}).encode(), method="POST",
        headers={"Content-Type": "application/json"})
    with pytest.raises(urllib.error.HTTPError) as exc:
        _opener().open(req, timeout=10)
    assert exc.value.code == 400
    assert "outside the 640x480 frame" in json.loads(exc.value.read())["error"]


def _xy(page):
    """(x, y, frames since load) read in one turn of the page's script: read one by one,
    a frame could blank #x or #y between the wait and the read (a CI run read '')."""
    got = page.wait_for_function(
        "() => { const x = document.getElementById('x'), y = document.getElementById('y');"
        " return x && y && x.textContent !== '' && y.textContent !== ''"
        " ? [x.textContent, y.textContent, since] : null; }").json_value()
    return float(got[0]), float(got[1]), int(got[2])


def test_contact_moves_on_the_page(station, page):
    page.goto(f"{station['base']}/?token={station['token']}")
    page.wait_for_function("() => since >= 5")
    x1, y1, f1 = _xy(page)
    page.wait_for_function(f"() => since >= {f1 + 10}")  # ~0.7 s of frames later
    x2, y2, f2 = _xy(page)
    page.wait_for_function("() => document.getElementById('frame').naturalWidth === 640")
    page.wait_for_function("() => document.querySelector('#loop-render') !== null")
    page.shot("live")
    assert f2 > f1
    assert math.hypot(x2 - x1, y2 - y1) > 2.0  # the blob circles at ~1.4 mm per frame
    assert -50 <= x2 <= 50 and -35 <= y2 <= 35
    rate = float(page.locator("#loop-render td").nth(1).text_content())
    # The render loop's rate reaches the page (how fast is the loop's benchmark's job:
    # beside a CPU hog the test station, not real-time, may tick below 1 kHz).
    assert math.isfinite(rate) and rate > 0
    assert page.locator("#link").text_content() == "no link"


def test_settings_saved_to_config(station, page):
    page.goto(f"{station['base']}/?token={station['token']}")
    page.wait_for_function("() => document.getElementById('threshold').value !== ''")
    page.fill("#threshold", "87")
    page.fill("#stiffness", "0.55")
    # Drag an ROI on the image: from (40, 30) to (600, 440) in image pixels (1:1 on screen).
    box = page.locator("#frame").bounding_box()
    page.mouse.move(box["x"] + 40, box["y"] + 30)
    page.mouse.down()
    page.mouse.move(box["x"] + 300, box["y"] + 200, steps=5)
    page.mouse.move(box["x"] + 600, box["y"] + 440, steps=5)
    page.mouse.up()
    page.wait_for_function("() => document.getElementById('roi').value === '40,30,560,410'")
    page.click("#save")
    page.wait_for_function("() => document.getElementById('msg').textContent.startsWith('saved')")
    page.shot("saved")
    cfg = load_config(station["config"])
    assert cfg.tracker.threshold == 87
    assert tuple(cfg.camera.roi_px) == (40, 30, 560, 410)
    # The softness went to the station's control record: the page shows it back.
    page.wait_for_function("() => document.getElementById('render').textContent"
                           ".includes('softness 0.55 N/mm')")
    # The tracker still finds the blob with the new ROI: the contact keeps moving.
    page.wait_for_function("() => since > 0")
    _, _, f1 = _xy(page)
    page.wait_for_function(f"() => since >= {f1 + 5}")
    assert page.locator("#x").text_content() != ""


def test_whole_experiment_session(station, page):
    page.goto(f"{station['base']}/experiment?token={station['token']}")
    page.fill("#participant", "P01")
    page.fill("#repeats", "3")
    page.fill("#seed", "42")
    page.click("#start")
    page.wait_for_selector("#answer-SS1")
    answers = {"SS1": "SS1", "SS2": "SS3", "SS3": "SS3", "SS4": "SS4"}
    shown = []
    for k in range(1, 13):
        page.wait_for_function(f"() => document.getElementById('trial').textContent"
                               f".startsWith('trial {k} of 12')")
        cur = page.locator("#current").text_content()
        shown.append(cur)
        if k == 7:
            page.shot("trial")
            # The station renders the stimulus: the live view reports it.
            state = _opener().open(f"{station['base']}/api/state?token={station['token']}",
                                   timeout=10).read().decode()
            assert f'"name": "{cur}"' in state
        page.click(f"#answer-{answers[cur]}")
    page.wait_for_selector("#donecard:not([hidden])")
    page.wait_for_function("() => document.getElementById('plot').complete && "
                           "document.getElementById('plot').naturalWidth > 0")
    page.shot("done")
    assert sorted(shown) == sorted(["SS1", "SS2", "SS3", "SS4"] * 3)
    assert page.locator("#acc-SS2").text_content() == "0.0 %"
    assert page.locator("#acc-SS1").text_content() == "100.0 %"
    assert page.locator("#average").text_content() == "75.0 %"
    rows = (station["results"] / "P01.csv").read_text().splitlines()
    assert len(rows) == 13 and rows[0].startswith("participant,trial,presented,answer")
    assert [r.split(",")[2] for r in rows[1:]] == shown
    import json

    rep = json.loads(_opener().open(f"{station['base']}/api/experiment/report?token="
                                    f"{station['token']}", timeout=10).read())
    assert rep["participants"] == ["P01"] and rep["confusion"]["accuracy"] == 0.75
    # A reload resumes the finished session's page from the server's state.
    page.reload()
    page.wait_for_selector("#donecard:not([hidden])")


def test_staircase_says_why_it_cannot_run_without_a_friction_model(station, page):
    """This station drives no motors and renders no texture: the page says so, offers no
    session, and the API refuses one in one line (a staircase would change nothing)."""
    import json

    page.goto(f"{station['base']}/experiment?token={station['token']}")
    page.wait_for_function("() => document.getElementById('st-msg').textContent"
                           ".includes('drives no motors')")
    assert page.locator("#st-start").is_disabled()
    assert page.locator("#st-model").text_content() == "none"
    page.shot("staircase-unavailable")
    req = urllib.request.Request(
        f"{station['base']}/api/staircase/start?token={station['token']}",
        data=json.dumps({"participant": "S9"}).encode(), method="POST",
        headers={"Content-Type": "application/json"})
    with pytest.raises(urllib.error.HTTPError) as exc:
        _opener().open(req, timeout=10)
    assert exc.value.code == 400
    error = json.loads(exc.value.read())["error"]
    assert "friction:MODEL.json" in error and "\n" not in error
    assert not (station["results"] / "staircase" / "S9.csv").exists()


def test_live_view_reads_clean(station, page):
    """Axis titles with units on the live plots (one axis per quantity), no image that
    failed to load, and no "NaN" anywhere on the page."""
    page.goto(f"{station['base']}/?token={station['token']}")
    page.wait_for_function("() => since >= 5")
    page.wait_for_function("() => document.getElementById('frame').naturalWidth === 640")
    # uPlot draws axis titles on its canvas: read them from the plots the page made.
    titles = page.evaluate("() => [...plotXY.axes, ...plotZF.axes].map(a => a.label)")
    assert titles == ["time (s)", "position (mm)", "time (s)", "indentation (mm)", "force (N)"]
    scales = page.evaluate("() => plotZF.series.slice(1).map(s => s.scale)")
    assert scales == ["mm", "N"]  # indentation and force on axes of their own
    broken = page.eval_on_selector_all(
        "img", "els => els.filter(e => !e.hidden && e.complete && e.naturalWidth === 0)"
               ".map(e => e.id || e.src)")
    assert broken == []
    assert "NaN" not in page.inner_text("body")
    page.shot("clean")
