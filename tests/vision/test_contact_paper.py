"""The paper's tracker (section II-B.1) on small frames whose answer is computed by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vision.contact import ContactTracker


def tracker_for(grey: np.ndarray, **kw) -> ContactTracker:
    """A tracker whose ROI is the whole frame at its own size: no resizing."""
    h, w = grey.shape
    return ContactTracker(roi_px=(0, 0, w, h), workspace_mm=(100.0, 70.0), processing_size=(w, h),
                          method="paper", **kw)


def test_gaussian_weights_by_hand():
    grey = np.array(
        [[200, 200, 200, 200],
         [200, 100, 140, 200],
         [200, 120, 200, 200]], dtype=np.uint8)
    # Finger pixels (< 150): 100 at (col 1, row 1), 140 at (2, 1), 120 at (1, 2).
    # Imin = 100, Imax = 140, sigma = 40 / 5 = 8.
    k100, k140, k120 = 1.0, math.exp(-(40**2) / (2 * 8**2)), math.exp(-(20**2) / (2 * 8**2))
    total = k100 + k140 + k120
    u = (1.5 * k100 + 2.5 * k140 + 1.5 * k120) / total
    v = (1.5 * k100 + 1.5 * k140 + 2.5 * k120) / total
    c = tracker_for(grey).process(grey)
    assert c is not None
    assert c.u_px == pytest.approx(u, abs=1e-12)
    assert c.v_px == pytest.approx(v, abs=1e-12)
    assert c.x_mm == pytest.approx((u / 4 - 0.5) * 100.0, abs=1e-9)
    assert c.y_mm == pytest.approx((0.5 - v / 3) * 70.0, abs=1e-9)
    assert c.area_mm2 == pytest.approx(3 * (100 / 4) * (70 / 3))


def test_sigma_zero_weighs_every_finger_pixel_equally():
    grey = np.full((3, 5), 220, np.uint8)
    grey[0, 0] = grey[2, 4] = 90  # two equally dark pixels: Imax = Imin, sigma = 0
    c = tracker_for(grey).process(grey)
    assert c is not None
    assert (c.u_px, c.v_px) == pytest.approx(((0.5 + 4.5) / 2, (0.5 + 2.5) / 2))
    assert (c.x_mm, c.y_mm) == pytest.approx((0.0, 0.0), abs=1e-12)


def test_no_pixel_below_threshold_is_no_contact():
    grey = np.full((120, 160), 150, np.uint8)  # "darker than 150" is strict
    assert tracker_for(grey).process(grey) is None
    grey[60, 80] = 149
    assert tracker_for(grey).process(grey) is not None


def test_threshold_and_beta_are_honoured():
    grey = np.full((1, 4), 255, np.uint8)
    grey[0, :3] = (60, 90, 120)
    # threshold 100 keeps 60 and 90; sigma = 30 / 2 = 15 with beta 2.
    c = tracker_for(grey, threshold=100, beta=2.0).process(grey)
    k90 = math.exp(-(30**2) / (2 * 15**2))
    assert c.u_px == pytest.approx((0.5 + 1.5 * k90) / (1 + k90), abs=1e-12)


def test_full_frame_pipeline_flip_roi_resize_grey():
    # A 640x480 BGR raw frame; ROI (0, 0, 640, 480) -> 160x120 is an exact 4x4 area average.
    raw = np.full((480, 640, 3), 230, np.uint8)
    # A dark 8x8 block on the raw image's left: 2x2 processing cells at cols 10-11, rows 50-51.
    raw[200:208, 40:48] = (60, 60, 60)
    tracker = ContactTracker(roi_px=(0, 0, 640, 480), workspace_mm=(100.0, 70.0),
                             image_flip="horizontal", method="paper")
    c = tracker.process(raw)
    # Mirrored: the block spans raw cols 40..48, so flipped cols 592..600, centre 596.
    assert c.u_px == pytest.approx(596.0)
    assert c.v_px == pytest.approx(204.0)
    assert c.x_mm == pytest.approx((596 / 640 - 0.5) * 100)  # on the user's right
    assert c.y_mm == pytest.approx((0.5 - 204 / 480) * 70)
    # Grey input gives the same answer as BGR.
    assert tracker.process(raw[:, :, 0]) == c


@pytest.mark.parametrize(("flip", "expect_sign"), [("none", (-1, 1)), ("horizontal", (1, 1)),
                                                    ("vertical", (-1, -1)), ("both", (1, -1))])
def test_flip_modes_put_the_contact_where_seen_from_above(flip, expect_sign):
    raw = np.full((480, 640), 230, np.uint8)
    raw[100:120, 100:120] = 50  # upper-left of the raw image
    c = ContactTracker(roi_px=(0, 0, 640, 480), image_flip=flip, method="paper").process(raw)
    assert (np.sign(c.x_mm), np.sign(c.y_mm)) == expect_sign


def test_roi_offset_maps_linearly_to_the_workspace():
    raw = np.full((480, 640), 230, np.uint8)
    roi = (24, 22, 592, 414)
    # Dark pixels outside the ROI are not seen.
    raw[:22, :] = 40
    raw[:, :24] = 40
    assert ContactTracker(roi_px=roi, method="paper").process(raw) is None
    # The whole ROI uniformly dark: the centroid is the ROI centre, i.e. (0, 0) mm.
    raw[22:436, 24:616] = 40
    c = ContactTracker(roi_px=roi, method="paper").process(raw)
    assert (c.x_mm, c.y_mm) == pytest.approx((0.0, 0.0), abs=1e-9)
    assert c.area_mm2 == pytest.approx(100.0 * 70.0)
    # A dark quarter at the ROI's top-left: centroid at (-25, +17.5) mm.
    raw[22:436, 24:616] = 230
    raw[22:229, 24:320] = 40
    c = ContactTracker(roi_px=roi, method="paper").process(raw)
    assert (c.x_mm, c.y_mm) == pytest.approx((-25.0, 17.5), abs=1e-9)
    assert c.area_mm2 == pytest.approx(100.0 * 70.0 / 4)


@pytest.mark.parametrize("kw", [{"roi_px": (0, 0, 0, 10)}, {"threshold": 0}, {"beta": 0},
                                {"method": "magic"}, {"image_flip": "sideways"}])
def test_bad_arguments_raise(kw):
    with pytest.raises(ValueError):
        ContactTracker(**kw)


def test_roi_outside_frame_is_an_error():
    with pytest.raises(ValueError, match="outside"):
        tracker = ContactTracker(roi_px=(600, 0, 100, 100), method="paper")
        tracker.process(np.zeros((480, 640), np.uint8))


def test_with_settings_keeps_the_rest():
    t = ContactTracker(roi_px=(0, 0, 640, 480), method="paper", beta=3.0)
    t2 = t.with_settings(threshold=120, image_flip="vertical")
    assert (t2.threshold, t2.image_flip, t2.beta, t2.method) == (120, "vertical", 3.0, "paper")
    assert t2.roi_px == t.roi_px
    with pytest.raises(TypeError, match="colour"):
        t.with_settings(colour="red")
