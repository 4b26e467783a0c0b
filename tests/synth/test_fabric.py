"""The one fabric model: stiffness range, deflection shape, the plane's error on it."""

from __future__ import annotations

import numpy as np
import pytest

from fydpad.fabric import Fabric
from vision.indentation import plane_delta_mm
from vision.recording import DEFAULT_IR_SENSORS_MM


def test_stiffness_spans_the_papers_range_over_the_motor_travel():
    f = Fabric()
    assert f.stiffness_at_theta(0.0) == pytest.approx(0.262, abs=0.002)
    assert f.stiffness_at_theta(1.2) == pytest.approx(1.04, abs=0.01)
    k = [f.stiffness_at_theta(t) for t in np.linspace(0, 1.2, 13)]
    assert np.all(np.diff(k) > 0)


def test_force_is_k_delta_for_small_dents_and_stiffens_for_deep_ones():
    f = Fabric()
    tension = f.tension_n(f.stretch_mm(0.3, 0.3))
    k = f.stiffness_n_per_mm(tension)
    assert f.force_n(0.5, tension) == pytest.approx(k * 0.5, rel=1e-3)
    assert f.force_n(40.0, tension) > 1.1 * k * 40.0
    assert f.force_n(-3.0, tension) == 0.0
    assert isinstance(f.force_n(2.0, tension), float)


def test_deflection_is_the_depth_under_the_finger_and_zero_at_the_rollers():
    f = Fabric()
    xf, yf, d = 12.0, -8.0, 30.0
    assert f.deflection_mm(xf, yf, xf, yf, d) == pytest.approx(d)
    assert f.deflection_mm(-f.roller_x_mm, yf, xf, yf, d) == pytest.approx(0.0, abs=1e-9)
    assert f.deflection_mm(f.roller_x_mm, 20.0, xf, yf, d) == pytest.approx(0.0, abs=1e-9)
    # Decays with distance from the finger, both along and across the stretch.
    along = f.deflection_mm(np.array([20.0, 35.0, 50.0, 65.0]), yf, xf, yf, d)
    across = f.deflection_mm(xf, np.array([5.0, 15.0, 30.0]), xf, yf, d)
    assert np.all(np.diff(along) < 0) and np.all(np.diff(across) < 0)
    assert np.all(along > 0) and np.all(across > 0)


def test_the_fabric_is_not_a_plane_the_plane_errs_like_the_papers():
    """Noise-free plane estimate (eq. 2 generalised) at random presses over the workspace,
    0-50 mm: off by a few mm RMS (paper: 2.88 mm), most under the sensor triangle."""
    f = Fabric()
    rng = np.random.default_rng(0)
    n = 4000
    x, y, d = rng.uniform(-50, 50, n), rng.uniform(-35, 35, n), rng.uniform(0, 50, n)
    s = np.asarray(DEFAULT_IR_SENSORS_MM)
    e = -f.deflection_mm(s[None, :, 0], s[None, :, 1], x[:, None], y[:, None], d[:, None])
    est = -plane_delta_mm(e, x, y)
    rmse = float(np.sqrt(np.mean((est - d) ** 2)))
    assert 2.0 < rmse < 4.0
    inside = (np.abs(x) < 10) & (np.abs(y) < 10) & (d > 40)
    assert np.mean(est[inside] - d[inside]) < -3.0  # the sag pulls the plane up there


def test_the_motor_plant_uses_this_fabric():
    from fydpad.motors.sim import FabricMotorPlant

    plant = FabricMotorPlant()
    assert isinstance(plant.fabric, Fabric)
    assert plant.stiffness_n_per_mm() == pytest.approx(Fabric().stiffness_at_theta(0.0))
