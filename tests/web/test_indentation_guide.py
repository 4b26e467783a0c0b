"""The indentation calibration guide in a real browser (Debian's Chromium, Playwright)
against a running station: reached from the station page, it walks through the steps
of ``fydpad calibrate indentation --protocol`` one at a time, each recording's press
points drawn on the workspace in order with their depth."""

from __future__ import annotations

from fydpad.indentation_protocol import presses, steps
from tests.web.test_browser import browser, page, station  # noqa: F401


def test_the_guide_walks_through_the_protocol(station, page):  # noqa: F811
    page.goto(f"{station['base']}/?token={station['token']}")
    page.click("a[href='indentation-guide']")
    page.wait_for_selector("section#step-1:not([hidden])")
    all_steps = steps()
    assert page.inner_text("#where") == f"step 1 of {len(all_steps)}"
    assert page.is_disabled("#back")
    first_recording = next(k for k, s in enumerate(all_steps, 1) if s.presses)
    for _ in range(first_recording - 1):
        page.click("#next")
    visible = page.locator("section.step:not([hidden])")
    assert visible.count() == 1
    assert "Recording 1" in visible.locator("h2").inner_text()
    ps = [p for p in presses() if p.recording == 1]
    circles = visible.locator("g.press")
    assert circles.count() == len(ps)
    assert [float(circles.nth(i).get_attribute("data-depth")) for i in range(len(ps))] == \
        [p.depth_mm for p in ps]
    page.shot("recording-1")
    for _ in range(len(all_steps)):
        page.click("#next") if not page.is_disabled("#next") else None
    assert page.inner_text("#where") == f"step {len(all_steps)} of {len(all_steps)}"
    assert "calibrate indentation" in page.locator(
        "section.step:not([hidden])").inner_text()
