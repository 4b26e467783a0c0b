"""Trajectories: speeds, contact phases, start without contact, determinism."""

from __future__ import annotations

import numpy as np
import pytest

from fydpad.synth.trajectory import HOP_SPEED_MM_S, TRAJECTORIES, TrajectoryParams, make_path


@pytest.mark.parametrize("name", TRAJECTORIES)
def test_every_trajectory_starts_untouched_touches_and_stays_in_the_workspace(name):
    p = TrajectoryParams()
    path = make_path(name, 10.0, np.random.default_rng(3), p)
    t = np.arange(path.x_mm.size) * path.dt_s
    assert path.duration_s == pytest.approx(10.0)
    # No contact (and the finger well above) during the lead-in: the IR baselines.
    lead = t < p.lead_in_s
    assert np.all(path.z_mm[lead] < -10.0)
    contact = path.z_mm > 0
    assert contact.any()
    # Onsets are smooth: the first contact comes after the lead-in, from above.
    first = np.flatnonzero(contact)[0]
    assert t[first] > p.lead_in_s
    assert np.all(np.abs(path.x_mm) <= 50.0) and np.all(np.abs(path.y_mm) <= 35.0)
    assert path.z_mm.max() <= 50.0
    speed = path.speed_mm_s()
    limit = 45.0 if name == "fast" else 40.0
    if name in ("presses", "protocol"):  # lifted hops between marks at a hand's pace
        assert speed.max() <= HOP_SPEED_MM_S * 1.01
        speed = speed[path.z_mm > -1.0]
    assert speed.max() <= limit * 1.01
    vz = np.abs(np.gradient(path.z_mm, path.dt_s))
    assert vz.max() <= 80.0 * 1.01


def test_peak_speeds_reach_what_the_paper_describes():
    rng = np.random.default_rng(5)
    circle = make_path("circle", 10.0, rng)
    assert circle.speed_mm_s().max() > 30.0
    fast = make_path("fast", 10.0, rng)
    assert fast.speed_mm_s().max() > 43.0
    tap = make_path("tapping", 10.0, rng)
    assert np.abs(np.gradient(tap.z_mm, tap.dt_s)).max() > 70.0
    assert tap.z_mm.max() > 20.0


def test_hover_trajectory_hovers_low_without_touching_and_touches_too():
    path = make_path("hover", 12.0, np.random.default_rng(1))
    low = (path.z_mm < 0) & (path.z_mm > -8.0)
    assert low.mean() > 0.3
    assert (path.z_mm > 0).any()


def test_light_touch_squeezes_indentations_but_keeps_contacts():
    heavy = make_path("tapping", 8.0, np.random.default_rng(2))
    light = make_path("tapping", 8.0, np.random.default_rng(2),
                      TrajectoryParams(light_max_mm=1.5))
    np.testing.assert_array_equal(heavy.z_mm > 0, light.z_mm > 0)
    assert light.z_mm.max() < 1.5 and light.z_mm.max() > 1.0


def test_same_seed_same_path_other_seed_other_path():
    a = make_path("walk", 6.0, np.random.default_rng(9))
    b = make_path("walk", 6.0, np.random.default_rng(9))
    c = make_path("walk", 6.0, np.random.default_rng(10))
    np.testing.assert_array_equal(a.x_mm, b.x_mm)
    assert not np.allclose(a.x_mm, c.x_mm)


def test_unknown_trajectory_is_refused():
    with pytest.raises(ValueError, match="trajectory must be one of"):
        make_path("spiral", 2.0, np.random.default_rng(0))
