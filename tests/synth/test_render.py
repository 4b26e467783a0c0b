"""The rendered frames against the ground truth: where the contact is, how it looks."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from fydpad.synth import SynthConfig, SyntheticPad
from fydpad.synth.finger import render_contact
from tests.synth.helpers import (
    darkness_centroid_mm,
    grey_from_above,
    patch,
    roi,
    steady_contact_frames,
    to_mm,
)


@pytest.fixture(scope="module")
def circle() -> SyntheticPad:
    return SyntheticPad(SynthConfig(trajectory="circle", seconds=10.0, seed=1))


def test_frames_have_the_cameras_size_and_type(circle):
    f = circle.frame(0)
    assert f.shape == (480, 640, 3) and f.dtype == np.uint8
    assert circle.frame_count == 300


def test_rest_fabric_is_clearly_brighter_than_the_papers_threshold_but_textured(circle):
    g = roi(circle, grey_from_above(circle, 3))  # finger far above: no contact
    assert not circle.truth(3).contact
    assert g.min() > 160.0
    assert 195.0 < np.median(g) < 225.0
    # Weave and noise: neighbouring pixels differ by a few grey levels.
    assert 1.5 < np.std(np.diff(g, axis=1)) < 12.0


def test_the_contacts_darkest_region_is_at_the_true_position(circle):
    rng = np.random.default_rng(0)
    frames = rng.choice(steady_contact_frames(circle), 6, replace=False)
    for k in frames:
        g = grey_from_above(circle, int(k))
        t = circle.truth(int(k))
        smooth = cv2.GaussianBlur(g, (0, 0), 4)
        v, u = np.unravel_index(int(np.argmin(smooth)), smooth.shape)
        x, y = to_mm(circle, u + 0.5, v + 0.5)
        assert np.hypot(x - t.x_mm, y - t.y_mm) < 1.5
        xc, yc = darkness_centroid_mm(circle, g)
        assert np.hypot(xc - t.x_mm, yc - t.y_mm) < 0.4
        assert smooth.min() < 100.0  # a firm contact is dark


def test_the_raw_frame_is_the_mirror_image_and_flip_is_a_choice():
    cfg = SynthConfig(trajectory="circle", seconds=4.0, seed=2)
    raw_h = SyntheticPad(cfg).frame(100)
    for flip, code in (("none", None), ("vertical", 0), ("both", -1)):
        other = SyntheticPad(replace(cfg, image_flip=flip)).frame(100)
        # The same scene; only the camera's mirroring differs.
        seen = cv2.flip(raw_h, 1)
        np.testing.assert_array_equal(other, seen if code is None else cv2.flip(seen, code))


def test_the_finger_shadow_is_paler_than_the_contact_and_towards_the_user(circle):
    k = steady_contact_frames(circle)[40]
    t = circle.truth(k)
    g = cv2.GaussianBlur(grey_from_above(circle, k), (0, 0), 3)
    base = cv2.GaussianBlur(grey_from_above(circle, 3), (0, 0), 3)
    u, v = circle.renderer.geom.to_px(t.x_mm, t.y_mm)
    sx, sy = circle.renderer.geom.px_per_mm
    ratio = g / base

    def at(dx_mm: float, dy_mm: float) -> float:
        return float(ratio[int(v - dy_mm * sy), int(u + dx_mm * sx)])

    # 20 mm towards the user (down the image) the finger's shadow dims the fabric ...
    behind = at(0.0, -20.0) if t.y_mm > -10 else at(0.0, -12.0)
    assert 0.75 < behind < 0.95
    # ... but not 20 mm away from the user, and much less than the contact.
    assert at(0.0, 20.0 if t.y_mm < 10 else 14.0) > 0.97
    assert at(0.0, 0.0) < 0.5


def test_contact_size_grows_with_indentation():
    pad = SyntheticPad(SynthConfig(trajectory="tapping", seconds=10.0, seed=17,
                                   mjpg_quality=None))
    ks = steady_contact_frames(pad)
    depths = np.array([pad.truth(k).indentation_mm for k in ks])
    pick = [ks[int(i)] for i in np.argsort(depths)[np.linspace(0, len(ks) - 1, 6).astype(int)]]
    areas = [patch(pad, grey_from_above(pad, k))[0].sum() for k in pick]
    d = [pad.truth(k).indentation_mm for k in pick]
    assert d[-1] - d[0] > 20.0
    assert np.all(np.diff(areas) > 0), (d, areas)


def test_motion_blur_spreads_the_contact_along_the_motion():
    cfg = SynthConfig(trajectory="fast", seconds=6.0, seed=4, mjpg_quality=None,
                      read_noise=0.0, shot_gain=0.0)
    pad_long = SyntheticPad(replace(cfg, exposure_s=1.0 / 30.0))
    pad_short = SyntheticPad(replace(cfg, exposure_s=1.0 / 2000.0))
    ks = steady_contact_frames(pad_long)
    speed = {k: pad_long.path.speed_mm_s()[round(k / 30.0 / pad_long.path.dt_s)]
             for k in ks}
    k = max(ks, key=lambda j: speed[j])
    assert speed[k] > 40.0
    t = pad_long.truth(k)
    x0, y0, _ = pad_long.path.at(t.t_s - 0.001)
    x1, y1, _ = pad_long.path.at(t.t_s + 0.001)
    direction = np.array([x1 - x0, y1 - y0]) / np.hypot(x1 - x0, y1 - y0)

    geom = pad_long.renderer.geom
    u, v = geom.to_px(t.x_mm, t.y_mm)
    win = (slice(int(v) - 70, int(v) + 70), slice(int(u) - 70, int(u) + 70))

    def blocked(pad: SyntheticPad) -> np.ndarray:
        """Fraction of light the contact blocks around it (the contact stage alone, in
        float: 8-bit frames would bury the difference in quantisation)."""
        c = pad.renderer.context(k)
        lum = np.ones((480, 640), np.float32)
        render_contact(lum, geom, pad.cfg.look, pad.cfg.fabric, c.xs, c.ys, c.zs)
        return 1.0 - lum[win]

    b_long, b_short = blocked(pad_long), blocked(pad_short)
    # The long exposure is the short one swept along the motion by the distance travelled
    # during the exposure (a box blur of that length), and not the short one itself.
    sx, sy = pad_long.renderer.geom.px_per_mm
    sweep_mm = speed[k] / 30.0
    swept = np.zeros_like(b_short)
    offsets = np.linspace(-0.5, 0.5, 41) * sweep_mm
    for o in offsets:
        m = np.float32([[1, 0, o * direction[0] * sx], [0, 1, -o * direction[1] * sy]])
        swept += cv2.warpAffine(b_short, m, b_short.shape[::-1], flags=cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_REPLICATE)
    swept /= offsets.size
    inner = (slice(5, -5), slice(5, -5))
    miss_swept = np.sqrt(np.mean((b_long - swept)[inner] ** 2))
    miss_still = np.sqrt(np.mean((b_long - b_short)[inner] ** 2))
    assert sweep_mm > 1.3
    assert miss_swept < 0.2 * miss_still, (miss_swept, miss_still)


def test_same_seed_same_frames_other_seed_other_frames():
    cfg = SynthConfig(trajectory="walk", seconds=5.0, seed=7)
    a = SyntheticPad(cfg).frame(90)
    b = SyntheticPad(cfg).frame(90)
    c = SyntheticPad(replace(cfg, seed=8)).frame(90)
    np.testing.assert_array_equal(a, b)
    assert np.abs(a.astype(int) - c).mean() > 1.0


def test_frames_can_be_rendered_in_any_order():
    pad = SyntheticPad(SynthConfig(trajectory="circle", seconds=3.0, seed=5))
    late = pad.frame(70)
    for k in range(3):
        pad.frame(k)
    np.testing.assert_array_equal(pad.frame(70), late)


def test_mjpg_stage_leaves_block_artefacts():
    cfg = SynthConfig(trajectory="circle", seconds=2.0, seed=5, read_noise=0.0, shot_gain=0.0)
    plain = SyntheticPad(replace(cfg, mjpg_quality=None)).frame(10).astype(float)
    jpeg = SyntheticPad(replace(cfg, mjpg_quality=60)).frame(10).astype(float)
    err = np.abs(jpeg - plain).mean(axis=2)
    assert 0.3 < err.mean() < 6.0
