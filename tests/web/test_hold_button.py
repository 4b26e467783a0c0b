"""The operator hold from the web view, end to end: a real station (`fydpad run --replay
... --web --teleop --record`) streaming to a real slave over loopback, its page in
headless Chromium. The Hold button holds the robot (the slave counts samples carrying the
hold), shows the hold, releases it; the endpoint needs the token; both changes are events
of the recording."""

from __future__ import annotations

import json
import math
import urllib.error
import urllib.request

import pytest

from fydpad.config import StationConfig, save_config
from tests.conftest import write_blob_recording
from tests.web.test_browser import (
    ARGS,
    CHROMIUM,
    TIMEOUT_MS,
    _opener,
    playwright_sync,
    start_station,
    stop_station,
)

pytestmark = pytest.mark.skipif(not CHROMIUM.exists(),
                                reason="no /usr/bin/chromium (apt-get install chromium)")


def _post_hold(base: str, token: str | None, body: dict) -> dict:
    q = f"?token={token}" if token else ""
    req = urllib.request.Request(f"{base}/api/hold{q}", data=json.dumps(body).encode(),
                                 method="POST", headers={"Content-Type": "application/json"})
    with _opener().open(req, timeout=10) as r:
        return json.loads(r.read())


def test_hold_button_holds_the_robot_and_is_recorded(tmp_path):
    from teleop import protocol as P
    from teleop.config import TeleopConfig
    from teleop.slave import SlaveThread

    positions = [(30 * math.cos(k / 14), 20 * math.sin(k / 14)) for k in range(900)]
    write_blob_recording(tmp_path / "rec", positions, fps=15.0)
    config = tmp_path / "pad.toml"
    save_config(StationConfig(), config)
    slave_cfg = TeleopConfig()
    # The subject is the hold, not the watchdog: a station starved by a loaded machine
    # must not trip a 250 ms watchdog and re-take the arm (a second hold count).
    slave_cfg.safety.watchdog_s = slave_cfg.safety.max_age_s = 5.0
    with SlaveThread(slave_cfg, bind="tcp://127.0.0.1:*") as slave:
        proc, base, token, err = start_station(
            ["--replay", str(tmp_path / "rec"), "--config", str(config), "--web", "0.0.0.0:0",
             "--teleop", slave.endpoint, "--record", str(tmp_path / "session"),
             "--no-video", "--duration", "60", "--no-realtime"], tmp_path)
        try:
            with pytest.raises(urllib.error.HTTPError) as refused:
                _post_hold(base, None, {"on": True})  # no token: refused, nothing held
            assert refused.value.code == 401
            with pytest.raises(urllib.error.HTTPError) as bad:
                _post_hold(base, token, {"on": "yes"})
            assert bad.value.code == 400
            with playwright_sync.sync_playwright() as pw:
                browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=ARGS,
                                             timeout=TIMEOUT_MS)
                page = browser.new_page()
                page.set_default_timeout(TIMEOUT_MS)
                page.goto(f"{base}/?token={token}")
                page.wait_for_function("() => since >= 3")
                assert page.text_content("#hold") == "Hold robot"
                page.click("#hold")
                page.wait_for_function(
                    "() => document.getElementById('hold').textContent === 'Release robot'")
                # The page shows what the station says: the next poll keeps it held.
                page.wait_for_function("() => since >= 10")
                assert page.get_attribute("#hold", "data-held") == "1"
                # The slave stands still on samples that carry the hold while it lasts:
                # one hold, and at least 3 more samples accepted under it.
                loop = slave.loop
                for _ in range(600):
                    if loop.status == P.STATUS_OPERATOR_HOLD:
                        break
                    page.wait_for_timeout(50)
                assert loop.status == P.STATUS_OPERATOR_HOLD
                accepted = loop.counts["accepted"]
                for _ in range(600):
                    if loop.counts["accepted"] >= accepted + 3:
                        break
                    page.wait_for_timeout(50)
                assert loop.counts["accepted"] >= accepted + 3
                assert loop.status == P.STATUS_OPERATOR_HOLD
                assert loop.counts["operator_holds"] == 1
                page.click("#hold")
                page.wait_for_function(
                    "() => document.getElementById('hold').textContent === 'Hold robot'")
                browser.close()
        finally:
            stop_station(proc, err)
    events = (tmp_path / "session" / "events.csv").read_text().splitlines()
    assert events[0] == "t_s,event,detail"
    rows = [line.split(",") for line in events[1:]]
    assert [(r[1], r[2]) for r in rows[:2]] == [("hold", "web"), ("release", "web")]
    assert 0 <= float(rows[0][0]) < float(rows[1][0])
