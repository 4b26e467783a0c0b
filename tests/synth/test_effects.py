"""Each real-footage condition changes what it should, and they combine."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from fydpad.synth import Effects, SynthConfig, SyntheticPad
from fydpad.synth.effects import AutoExposure
from tests.synth.helpers import grey_from_above, patch, processed, roi, steady_contact_frames
from vision.contact import ContactTracker

CLEAN = SynthConfig(trajectory="walk", seconds=8.0, seed=21, mjpg_quality=None)


def with_effect(cfg: SynthConfig = CLEAN, **on: bool) -> SyntheticPad:
    return SyntheticPad(replace(cfg, effects=Effects(**on)))


def test_clean_footage_has_nothing_darker_than_the_threshold_without_contact():
    pad = with_effect()
    for k in (2, 12, 22):
        assert roi(pad, grey_from_above(pad, k)).min() > 150.0


def test_uneven_light_darkens_the_corners_far_more_than_the_lens_alone():
    def corner_over_centre(pad: SyntheticPad) -> float:
        g = cv2.GaussianBlur(grey_from_above(pad, 2), (0, 0), 4)
        corners = [g[:30, :30], g[:30, -30:], g[-30:, :30], g[-30:, -30:]]
        return min(float(c.mean()) for c in corners) / float(g[220:260, 300:340].mean())

    assert corner_over_centre(with_effect()) > 0.85
    assert corner_over_centre(with_effect(uneven_light=True)) < 0.72


def _mean_levels(pad: SyntheticPad, frames) -> np.ndarray:
    # The top band of the view: away from the finger and hand in these frames.
    return np.array([grey_from_above(pad, k)[30:90, 40:600].mean() for k in frames])


def test_room_light_dips_by_a_third_for_seconds_and_flickers():
    pad = with_effect(room_light=True)
    room = pad.renderer.room_light
    assert room is not None and room.dips
    t0, t1 = room.dips[0]
    assert 1.5 <= t1 - t0 <= 3.5
    assert room.dip_gain(0.5 * (t0 + t1)) == pytest.approx(2.0 / 3.0)
    frames = np.arange(0, 24)  # lead-in: the finger is far away
    clean = _mean_levels(with_effect(), frames)
    ratio = _mean_levels(pad, frames) / clean
    gains = np.array([room.gain(k / 30.0) for k in frames])
    np.testing.assert_allclose(ratio, gains, atol=0.01)
    # Flicker: the light changes from frame to frame even outside the dips.
    outside = np.array([room.dip_gain(k / 30.0) == 1.0 for k in frames])
    assert np.std(np.diff(gains[outside])) > 0.01
    mid = int(0.5 * (t0 + t1) * 30)
    assert _mean_levels(pad, [mid])[0] / _mean_levels(with_effect(), [mid])[0] == \
        pytest.approx(room.gain(mid / 30.0), abs=0.01)
    assert room.gain(mid / 30.0) < 0.75


def test_auto_exposure_swings_the_whole_image_by_up_to_20_percent():
    pad = with_effect(auto_exposure=True)
    frames = np.arange(0, 240, 6)
    ratio = _mean_levels(pad, frames) / _mean_levels(with_effect(), frames)
    assert ratio.max() <= 1.2 + 0.01 and ratio.min() >= 0.8 - 0.01
    assert ratio.max() - ratio.min() > 0.15


def test_auto_exposure_chases_a_room_light_dip_late_and_partly():
    pad = with_effect(room_light=True, auto_exposure=True)
    room, ae = pad.renderer.room_light, pad.renderer.auto_exposure
    assert room is not None and ae is not None
    t0, t1 = room.dips[0]
    alone = AutoExposure(np.random.default_rng(0))
    alone.a, alone.w, alone.ph = ae.a, ae.w, ae.ph  # the same hunting, no chase
    # Just into the dip the camera has not reacted yet; a second later it makes up for
    # part of the dip (never past +-20 %).
    onset = t0 - 0.23  # the dip's 0.25 s edge has just begun
    assert room.dip_gain(onset) < 0.999
    assert ae.gain(onset) == pytest.approx(alone.gain(onset), abs=0.01)
    late = min(t0 + 1.2, t1)
    assert ae.gain(late) > alone.gain(late) * 1.1 or ae.gain(late) >= 1.2 - 1e-9
    ts = np.linspace(0, 8, 400)
    gains = np.array([ae.gain(t) for t in ts])
    assert gains.min() >= 0.8 - 1e-9 and gains.max() <= 1.2 + 1e-9


def test_daylight_makes_a_gradient_that_drifts():
    pad = with_effect(daylight=True)
    base = with_effect()

    def slope_and_angle(k: int) -> tuple[float, float]:
        r = cv2.GaussianBlur(grey_from_above(pad, k) / grey_from_above(base, k), (0, 0), 8)
        h, w = r.shape
        gx = (r[:, -40:].mean() - r[:, :40].mean()) / (2 * (w - 40) / w)
        gy = (r[-40:, :].mean() - r[:40, :].mean()) / (2 * (h - 40) / h)
        return float(np.hypot(gx, gy)), float(np.arctan2(gy, gx))

    a0, th0 = slope_and_angle(3)
    a1, th1 = slope_and_angle(20)
    # A gradient of the daylight's strength across the frame (0.15-0.3 each side) ...
    assert 0.12 < a0 < 0.33 and 0.12 < a1 < 0.33
    # ... from the side the renderer's daylight says.
    light = pad.renderer.daylight
    assert light is not None
    assert abs(np.angle(np.exp(1j * (th0 - light.angle(3 / 30.0))))) < 0.1
    assert abs(np.angle(np.exp(1j * (th1 - light.angle(20 / 30.0))))) < 0.1


def test_daylight_direction_and_strength_change_over_seconds():
    from fydpad.synth.effects import Daylight

    d = Daylight(np.random.default_rng(3), with_effect().renderer.geom)
    angles = np.array([d.angle(t) for t in np.linspace(0, 20, 200)])
    strengths = np.array([d.strength(t) for t in np.linspace(0, 20, 200)])
    assert np.ptp(angles) > 0.2
    assert np.ptp(strengths) > 0.03
    assert strengths.min() >= 0.15 - 1e-9 and strengths.max() <= 0.3 + 1e-9


def test_stains_are_darker_than_the_threshold_and_stay_put():
    pad = with_effect(stains=True)
    g0, g1 = roi(pad, grey_from_above(pad, 2)), roi(pad, grey_from_above(pad, 20))
    dark0, dark1 = g0 < 150, g1 < 150
    assert dark0.sum() > 100
    assert (dark0 & dark1).sum() > 0.8 * dark0.sum()
    # The paper's method takes a stain for a finger.
    tracker = ContactTracker(roi_px=pad.cfg.roi_px, workspace_mm=pad.cfg.workspace_mm,
                             image_flip=pad.cfg.image_flip, method="paper")
    assert tracker.process(pad.frame(2)) is not None


def test_a_hovering_fingers_shadow_is_dark_with_the_effect_and_faint_without():
    cfg = replace(CLEAN, trajectory="hover", seconds=10.0, seed=5)
    on, off = with_effect(cfg, hover=True), with_effect(cfg)
    low = [k for k in range(on.frame_count) if -2.5 < on.truth(k).z_mm < -1.0]
    assert low, "the hover trajectory must bring the finger close"
    for k in low[:: max(len(low) // 3, 1)][:3]:
        assert not on.truth(k).contact
        # As the paper's tracker sees it (160 x 120): a shadow below its threshold ...
        assert processed(on, k).min() < 150.0
        # ... that without the effect stays clearly above it.
        assert processed(off, k).min() > 155.0
    # Between contacts the finger travels low with the effect.
    assert on.cfg.path.travel_height_mm <= 3.0


def test_the_hand_shadows_the_users_edge_of_the_view_only():
    cfg = replace(CLEAN, trajectory="circle", seed=3)
    on, off = with_effect(cfg, hand_shadow=True), with_effect(cfg)
    k = next(j for j in steady_contact_frames(off) if off.truth(j).y_mm > -5.0)
    g_on, g_off = grey_from_above(on, k), grey_from_above(off, k)
    assert g_on[-30:].mean() < 0.8 * g_off[-30:].mean()
    assert g_on[:40].mean() == pytest.approx(g_off[:40].mean(), rel=0.01)
    assert g_on[-30:].min() < 150.0


def test_light_touches_are_shallow_and_pale():
    cfg = replace(CLEAN, trajectory="circle", seconds=6.0, seed=3)
    light, firm = with_effect(cfg, light_touch=True), with_effect(cfg)
    ks = steady_contact_frames(light)[20::25][:3]
    for k in ks:
        assert 0.0 < light.truth(k).indentation_mm < 1.5
        _, lo_light = patch(light, grey_from_above(light, k))
        _, lo_firm = patch(firm, grey_from_above(firm, k))
        assert 110.0 < lo_light < 150.0
        assert lo_firm < 90.0


def test_fast_strokes_reach_45_mm_s_with_a_1_30_s_exposure():
    pad = with_effect(replace(CLEAN, trajectory="circle"), fast=True)
    assert pad.cfg.exposure == pytest.approx(1.0 / 30.0)
    assert with_effect().cfg.exposure == pytest.approx(1.0 / 60.0)
    assert 42.0 < pad.path.speed_mm_s().max() <= 45.5
    assert with_effect(replace(CLEAN, trajectory="circle")).path.speed_mm_s().max() <= 40.5


def test_all_effects_combine_and_break_the_papers_tracker():
    pad = SyntheticPad(replace(CLEAN, seconds=4.0, effects=Effects.all()))
    assert set(pad.cfg.effects.names()) == set(Effects().__dataclass_fields__)
    tracker = ContactTracker(roi_px=pad.cfg.roi_px, workspace_mm=pad.cfg.workspace_mm,
                             image_flip=pad.cfg.image_flip, method="paper")
    false = sum(tracker.process(pad.frame(k)) is not None for k in range(0, 24, 4))
    assert false >= 3  # frames of the lead-in, with no finger near the fabric
    assert all(not pad.truth(k).contact for k in range(0, 24, 4))
