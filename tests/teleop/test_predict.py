"""The slave's extrapolator (predict.py)."""

from __future__ import annotations

import numpy as np
import pytest

from teleop.predict import IMMPredictor, Predictor


def test_quadratic_motion_is_extrapolated_exactly():
    """A constant-acceleration path (a tap's turn) is predicted without error."""
    p = Predictor(window=6, degree=2, max_horizon_s=0.1)
    f = lambda t: np.array([3.0 + 40 * t - 800 * t * t])  # noqa: E731
    for k in range(6):
        p.add(k / 30, f(k / 30))
    t = 5 / 30 + 0.04
    assert p.predict_flat(t)[0] == pytest.approx(f(t)[0], abs=1e-9)


def test_short_history_uses_lower_degree():
    p = Predictor(6, 2)
    assert p.predict(1.0) is None
    p.add(0.0, np.array([1.0]))
    assert p.predict_flat(0.5)[0] == 1.0  # one sample: hold
    p.add(0.1, np.array([2.0]))
    assert p.predict_flat(0.15)[0] == pytest.approx(2.5)  # two: the line


def test_horizon_is_capped():
    """A stale history does not fly off: extrapolation stops at max_horizon_s."""
    p = Predictor(4, 1, max_horizon_s=0.05)
    p.add(0.0, np.array([0.0]))
    p.add(0.1, np.array([10.0]))
    assert p.predict_flat(5.0)[0] == pytest.approx(15.0)


def test_times_must_increase():
    p = Predictor()
    p.add(1.0, np.zeros(3))
    with pytest.raises(ValueError, match="not after"):
        p.add(1.0, np.zeros(3))


def test_noise_is_not_amplified_much():
    """With 0.1 mm noise on a still finger the prediction error stays near the noise."""
    rng = np.random.default_rng(1)
    p = Predictor(6, 2, 0.12)
    errs = []
    for k in range(300):
        p.add(k / 30, rng.normal(0, 0.1, 1))
        if k > 6:
            errs.append(abs(p.predict_flat(k / 30 + 1 / 30)[0]))
    assert np.mean(errs) < 0.35


def _one_step_errors(pred, z_true, noise_mm, seed=2):
    """|prediction one 30 fps frame ahead - truth| after each noisy sample."""
    rng = np.random.default_rng(seed)
    errs = []
    for k in range(len(z_true) - 1):
        pred.add(k / 30, np.array([z_true[k] + rng.normal(0, noise_mm)]))
        if k >= 6:
            errs.append(abs(pred.predict_flat((k + 1) / 30)[0] - z_true[k + 1]))
    return np.array(errs)


def test_imm_smooths_a_still_noisy_indentation_better_than_the_quadratic():
    """0.4 mm noise (the IR indentation's) on a still finger: the quadratic hands it on
    amplified, the IMM's calm model averages it out."""
    z = np.full(300, 5.0)
    imm = _one_step_errors(IMMPredictor(0.5, (3e4, 3e8)), z, 0.4)
    poly = _one_step_errors(Predictor(4, 2), z, 0.4)
    assert imm.mean() < 0.5 * poly.mean(), (imm.mean(), poly.mean())


def test_imm_follows_a_tap():
    """A tap (sin^2, 7.6 mm deep, 80 mm/s peak) with little noise: the quick model takes
    over; the one-frame-ahead error stays near the quadratic's, under 1 mm on average."""
    t = np.arange(60) / 30
    z = 7.6 * np.sin(np.pi * np.clip(t - 0.5, 0, 0.3) / 0.3) ** 2
    imm = _one_step_errors(IMMPredictor(0.5, (3e4, 3e8)), z, 0.1)
    poly = _one_step_errors(Predictor(4, 2), z, 0.1)
    assert imm.mean() < 1.0 and imm.mean() < 1.5 * poly.mean(), (imm.mean(), poly.mean())


def test_imm_extrapolates_constant_acceleration():
    """Noise-free constant acceleration: once converged, the prediction is on the path."""
    p = IMMPredictor(0.05, (1e2, 1e6), max_horizon_s=0.1)
    f = lambda t: 3.0 + 40 * t - 300 * t * t  # noqa: E731
    for k in range(60):
        p.add(k / 30, np.array([f(k / 30)]))
    t = 59 / 30 + 0.03
    assert p.predict_flat(t)[0] == pytest.approx(f(t), abs=0.02)


def test_imm_interface_matches_the_polynomial():
    p = IMMPredictor(0.5, (3e4, 3e8))
    assert p.predict(0.0) is None and len(p) == 0
    p.add(0.0, np.array([2.0]))
    assert p.predict_flat(0.05)[0] == pytest.approx(2.0)  # one sample: at rest there
    assert p.latest()[0] == 2.0
    with pytest.raises(ValueError, match="not after"):
        p.add(0.0, np.array([2.0]))
    p.reset()
    assert len(p) == 0
    with pytest.raises(ValueError, match="noise"):
        IMMPredictor(0.0, (1.0,))


def test_configured_imm_keeps_a_sliding_depth_calm():
    """A slow slide (5 +- 2.5 mm at 0.4 Hz) with 0.4 mm IR-like noise, from a touch-down:
    the configured three models with a sticky calm one predict one frame ahead ~25 %
    better than the former two equal models (jerk 3e4 / 3e8, stay 0.98), which took
    noise for presses (docs/teleop.md)."""
    from teleop.config import PredictionConfig
    pc = PredictionConfig()
    t = np.arange(300) / 30
    z = 5.0 + 2.5 * np.sin(2 * np.pi * 0.4 * t)
    for seed in (1, 2, 3):
        new = IMMPredictor(pc.noise_z_mm, pc.jerk_psd_z, pc.mode_stay, 0.12, pc.mode_start)
        old = IMMPredictor(0.5, (3e4, 3e8), 0.98, 0.12)
        for p in (new, old):
            p.add(-1 / 30, np.array([0.0]))  # the lifted sample the slave seeds with
        e_new = _one_step_errors(new, z, 0.4, seed).mean()
        e_old = _one_step_errors(old, z, 0.4, seed).mean()
        assert e_new < 0.85 * e_old, (seed, e_new, e_old)


def test_imm_per_model_stay_and_start_are_checked():
    p = IMMPredictor(0.5, (1e3, 1e8), stay=(0.99, 0.9), start=(0.1, 0.9))
    p.add(0.0, np.array([0.0]))
    p.add(1 / 30, np.array([1.0]))
    assert np.isfinite(p.predict_flat(0.05)[0])
    with pytest.raises(ValueError, match="start"):
        IMMPredictor(0.5, (1e3, 1e8), start=(1.0,))
    with pytest.raises(ValueError, match="stay"):
        IMMPredictor(0.5, (1e3, 1e8), stay=(0.99, 1.5))


def test_imm_step_is_one_kalman_step_per_mixed_model():
    """The vectorised IMM cycle equals its definition: mix the models' states, then one
    kalman_step per model, weights by the likelihoods (Blom & Bar-Shalom)."""
    from teleop.predict import imm_start, imm_step, kalman_step, transition_matrix
    jerk, stay = (3e3, 3e5, 3e8), (0.998, 0.98, 0.95)
    st = imm_start(0.0, 0.5, 3, mu0=(0.02, 0.08, 0.9))
    rng = np.random.default_rng(4)
    for k in range(40):
        z, dt = float(rng.normal(k * 0.2, 0.5)), float(rng.uniform(0.01, 0.05))
        trans = transition_matrix(stay, 3)
        cbar = trans.T @ st.mu
        w = trans * st.mu[:, None] / cbar[None, :]
        ref_x, ref_like = [], []
        for j in range(3):
            x0 = w[:, j] @ st.x
            d = st.x - x0
            p0 = np.einsum("i,ikl->kl", w[:, j], st.p + d[:, :, None] * d[:, None, :])
            xj, _, lj = kalman_step(x0, p0, dt, z, 0.5, jerk[j])
            ref_x.append(xj)
            ref_like.append(lj)
        mu = np.array(ref_like) * cbar
        st = imm_step(st, dt, z, 0.5, jerk, stay)
        np.testing.assert_allclose(st.x, np.array(ref_x), rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(st.mu, mu / mu.sum(), rtol=1e-9, atol=1e-12)


def test_imm_settings_of_another_model_count_name_the_field():
    """A config from before the third model (two jerks, the new three-value defaults for
    stay and start) gets an error that names the fields, not a NumPy broadcast error."""
    with pytest.raises(ValueError, match=r"prediction.mode_stay has 3 values for the 2 models"):
        IMMPredictor(0.5, (3e4, 3e8), (0.998, 0.98, 0.95))
    with pytest.raises(ValueError, match=r"prediction.mode_start must be 2 values"):
        IMMPredictor(0.5, (3e4, 3e8), 0.98, start=(0.02, 0.08, 0.9))
