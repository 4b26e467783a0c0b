"""The thesis' network (Lin 2016, section 3.2): shipped weights, features, training, model files."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from fydpad.errors import UserError
from fydpad.texture.families.mlp.model import (
    THESIS_MODEL,
    MlpNet,
    bandpass_fft,
    delta_force,
    model_to_json,
    parse_mlp,
    thesis_model,
    velocity_xy,
)
from fydpad.texture.families.mlp.train import TrainConfig, fit_mlp, thirds, train
from fydpad.texture.family import read_model_json, save_model_json

# Tables 3.2-3.4 of the thesis, transcribed here independently of the shipped file.
VX = [0.87, -1.87, 0.13, -1.32, -1.26, 1.09, 1.91, 2.91, -1.67, -0.53]
VY = [2.38, -2.04, 2.86, 0.61, -2.05, 2.21, 0.97, 0.44, -1.46, -2.45]
DF = [-1.63, -1.17, 0.81, 2.58, -1.74, 1.65, 2.14, -0.23, -1.97, 1.66]
BIAS = [-2.99, 2.33, -1.66, 1.16, -0.04, 1.00, 0.61, 1.75, -2.35, -3.013]
OUT = [-0.41, -0.39, -0.07, 0.14, 0.04, 0.57, -0.22, -0.26, 0.51, 0.02]


def load_mlp(path):
    return parse_mlp(read_model_json(path), str(path))


def _by_hand(vx: float, vy: float, df: float) -> float:
    """Eq. 4-7 with plain floats: logsig hidden layer, purelin output, bias 0.11."""
    out = 0.11
    for j in range(10):
        net = VX[j] * vx + VY[j] * vy + DF[j] * df + BIAS[j]
        out += OUT[j] / (1.0 + math.exp(-net))
    return out


def test_shipped_thesis_weights_reproduce_a_forward_pass_by_hand():
    m = thesis_model()
    assert not m.scaling.known and m.provenance["unknown"]
    # The file assumes v in m/s (input in mm/s, scale 0.001) and delta f in N.
    pts = [(0.0, 0.0, 0.0), (20.0, 0.0, 0.05), (-35.0, 12.0, -0.3), (1000.0, -800.0, 2.0)]
    want = [_by_hand(vx / 1000, vy / 1000, df) for vx, vy, df in pts]
    # The family's weights (scaling and logsig folded into tanh) against the plain equations.
    from fydpad.texture.families.mlp.render import MlpTexture

    arr = np.array(pts)
    np.testing.assert_allclose(MlpTexture(m).raw(arr[:, 0], arr[:, 1], arr[:, 2]), want,
                               rtol=0, atol=1e-12)


def test_thesis_model_is_packaged():
    import tomllib

    from tests.conftest import REPO

    data = tomllib.loads((REPO / "pyproject.toml").read_text())
    globs = data["tool"]["setuptools"]["package-data"]["fydpad"]
    rel = THESIS_MODEL.relative_to(REPO / "fydpad").as_posix()
    assert any(__import__("fnmatch").fnmatch(rel, g) for g in globs), (rel, globs)


def test_bandpass_fft_keeps_the_band_exactly():
    fs = 2000.0
    t = np.arange(4000) / fs  # 2 s: 0.5 Hz bins, every tone on a bin
    keep = np.sin(2 * np.pi * 50 * t) + 0.3 * np.cos(2 * np.pi * 480 * t)
    x = keep + 2.0 * np.sin(2 * np.pi * 2 * t) + np.sin(2 * np.pi * 700 * t) + 3.0
    np.testing.assert_allclose(bandpass_fft(x, fs, (5.0, 500.0)), keep, atol=1e-9)


def test_delta_force_is_force_minus_its_moving_mean_across_blocks():
    fs, tau = 1000.0, 0.05
    f = np.concatenate([np.ones(50), 2.0 * np.ones(300)])
    df, _ = delta_force(f, fs, tau)
    alpha = 1 - math.exp(-1 / (tau * fs))
    k = np.arange(300)
    np.testing.assert_allclose(df[:50], 0.0)
    np.testing.assert_allclose(df[50:], (1 - alpha) ** k, rtol=1e-12)  # a 1 N step decays
    a, m = delta_force(f[:120], fs, tau)
    b, _ = delta_force(f[120:], fs, tau, m)
    np.testing.assert_allclose(np.concatenate([a, b]), df, atol=1e-15)


def test_velocity_follows_the_direction_of_held_camera_positions():
    # positions held for 33 samples (camera frames), moving at 45 degrees, then along -y
    x = np.repeat([0.0, 1.0, 2.0, 2.0, 2.0], 33)
    y = np.repeat([0.0, 1.0, 2.0, 1.0, 0.0], 33)
    v = np.full(x.size, 30.0)
    vx, vy, last = velocity_xy(x, y, v)
    np.testing.assert_allclose(np.hypot(vx, vy), 30.0)
    np.testing.assert_allclose(vx[:33], 30.0)  # no move yet: +x
    np.testing.assert_allclose(vx[33:99], 30 / math.sqrt(2))
    np.testing.assert_allclose(vy[99:], -30.0, atol=1e-12)
    assert last[:2] == (2.0, 0.0)


def test_thirds_are_contiguous_and_cover_the_recording():
    s = thirds(10)
    assert [(a.start, a.stop) for a in s] == [(0, 3), (3, 6), (6, 10)]


def _teacher(seed: int = 5):
    rng = np.random.default_rng(seed)
    return MlpNet(rng.uniform(-2, 2, (10, 3)), rng.uniform(-1, 1, 10),
                  rng.uniform(-1, 1, 10), 0.1)


def _teacher_problem():
    teacher = _teacher()
    rng = np.random.default_rng(1)
    u, u_test = rng.uniform(-1, 1, (1000, 3)), rng.uniform(-1, 1, (2000, 3))
    lo, hi = teacher.forward(u).min(), teacher.forward(u).max()

    def target(x):  # scaled to [-1, 1] like mapminmax
        return 2 * (teacher.forward(x) - lo) / (hi - lo) - 1

    return u, target(u), u_test, target(u_test)


def _r2_or_none(cfg):
    u, y, u_test, truth = _teacher_problem()
    try:
        net, _ = train(u, y, None, None, cfg)
    except UserError:
        return None  # diverged in the first epoch
    return 1 - np.mean((truth - net.forward(u_test)) ** 2) / np.var(truth)


def test_thesis_training_rule_learns_a_known_function():
    """Per-sample steepest descent, weights in [-10, 10], 10 logsig units (the thesis'),
    at learning rate 0.3: the function of a known teacher network, on unseen inputs."""
    from fydpad.texture.families.mlp.train import init_net

    cfg = TrainConfig(max_epochs=150, learning_rate=0.3)
    assert (cfg.init_range, cfg.hidden, cfg.mode) == (10.0, 10, "online")
    for seed in (0, 1, 2):
        r2 = _r2_or_none(replace(cfg, seed=seed))
        assert r2 is not None and r2 > 0.9, (seed, r2)
    _, _, u_test, truth = _teacher_problem()
    r2_0 = 1 - np.mean((truth - init_net(3, cfg).forward(u_test)) ** 2) / np.var(truth)
    assert r2_0 < 0  # the untrained network is far from it


def test_the_thesis_learning_rate_is_unstable_per_sample():
    """Finding: with the thesis' 0.9 the same problem diverges or fails for most seeds
    (measured: 0 of seeds 0-5 reach R^2 0.8; 2 of 0-9), which is why docs/texture_mlp.md
    reports the thesis settings and a stable variant side by side."""
    cfg = TrainConfig(max_epochs=60)
    assert cfg.learning_rate == 0.9
    ok = [r for r in (_r2_or_none(replace(cfg, seed=s)) for s in range(6))
          if r is not None and r > 0.8]
    assert len(ok) <= 2


def test_training_is_deterministic_for_a_seed():
    teacher = _teacher()
    rng = np.random.default_rng(2)
    u = rng.uniform(-1, 1, (300, 3))
    y = teacher.forward(u) / 3
    for mode in ("online", "batch"):
        a, _ = train(u, y, u[:50], y[:50], TrainConfig(max_epochs=20, seed=3, mode=mode))
        b, _ = train(u, y, u[:50], y[:50], TrainConfig(max_epochs=20, seed=3, mode=mode))
        c, _ = train(u, y, u[:50], y[:50], TrainConfig(max_epochs=20, seed=4, mode=mode))
        np.testing.assert_array_equal(a.w_in, b.w_in)
        np.testing.assert_array_equal(a.w_out, b.w_out)
        assert not np.array_equal(a.w_in, c.w_in)


def test_validation_stop_keeps_the_best_validation_weights():
    rng = np.random.default_rng(0)
    u = rng.uniform(-1, 1, (200, 3))
    y = rng.standard_normal(200) * 0.3  # noise: validation cannot keep improving
    uv, yv = rng.uniform(-1, 1, (200, 3)), rng.standard_normal(200) * 0.3
    net, rep = train(u, y, uv, yv, TrainConfig(max_epochs=500, mode="batch", init_range=0.5))
    assert rep.stop == "validation" and rep.epochs == rep.best_epoch + 6
    assert np.mean((yv - net.forward(uv)) ** 2) == pytest.approx(min(rep.val_mse))


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    from benchmarks.bench_mlp_accuracy import stroke

    scans = [stroke("felt", s, 3.0, seed=1) for s in (10.0, 30.0)]
    model, rep, _ = fit_mlp(scans, TrainConfig(mode="batch", init_range=0.5, max_epochs=50))
    return scans, model, rep


def test_fit_round_trip_and_family_render_equals_tick(fitted, tmp_path):
    from fydpad.texture.families import load_family
    from fydpad.texture.family import finger_from_scan

    scans, model, _ = fitted
    p = save_model_json(model_to_json(model), tmp_path / "felt_mlp.json")
    back = load_mlp(p)
    np.testing.assert_array_equal(back.net.w_in, model.net.w_in)
    np.testing.assert_array_equal(back.scaling.in_scale, model.scaling.in_scale)
    fam = load_family(f"mlp:{p}")
    assert fam.kind == "mlp" and fam.tick_channels == ("vibration",)
    fb = finger_from_scan(scans[0])
    block = fam.render(fb, "vibration")
    fam.reset()
    ticks = np.array([fam.tick(fb.t_s[k], bool(fb.contact[k]), fb.x_mm[k], fb.y_mm[k],
                               fb.speed_mm_s[k], fb.force_n[k])[0] for k in range(fb.t_s.size)])
    np.testing.assert_allclose(ticks, block, rtol=1e-9, atol=1e-12)
    assert np.std(block) > 0


def test_fit_needs_force(tmp_path):
    from fydpad.synth.texture_scans import generate_scan
    from fydpad.texture.families import fit_family

    with pytest.raises(UserError, match="column 'force_n'"):
        fit_family("mlp", [generate_scan("felt", 10.0, 1.0, seed=1)])
    with pytest.raises(UserError, match=r"unknown option.*lerning_rate"):
        fit_family("mlp", [generate_scan("felt", 10.0, 1.0, seed=1)], lerning_rate=0.1)
    scan = generate_scan("felt", 10.0, 1.0, seed=1, friction=True)
    with pytest.raises(UserError, match=r"mlp fit: option mode must be .* not 'fast'"):
        fit_family("mlp", [scan], mode="fast")


def _bad(tmp_path, edit, name="bad.json"):
    data = json.loads(THESIS_MODEL.read_text())
    edit(data)
    p = tmp_path / name
    p.write_text(json.dumps(data))
    return p


@pytest.mark.parametrize(("edit", "match"), [
    (lambda d: d.pop("weights"), r"bad\.json: missing key 'weights'"),
    (lambda d: d["weights"]["input"].pop(), r"bad\.json: weights: key 'input_bias' has shape"),
    (lambda d: d["weights"].update(output=[1.0] * 9), r"weights: key 'output' has shape"),
    (lambda d: d["weights"].update(output_bias="x"), r"key 'output_bias' must be numbers"),
    (lambda d: d["scaling"].update(input_scale=[1, 2]), r"scaling: key 'input_scale' has shape"),
    (lambda d: d.update(format_version=7), r"bad\.json: key 'format_version' is 7"),
    (lambda d: d.update(kind="grating"), r"key 'kind' is 'grating'"),
    (lambda d: d.update(band_hz=[500, 5]), r"'band_hz' must be positive and ordered"),
    (lambda d: d["delta_force"].update(tau_s=0), r"'delta_force.tau_s' must be positive"),
    (lambda d: d.update(sample_rate_hz=1e300), r"the rate at most 1e\+06 Hz \(got 1e\+300 Hz"),
    (lambda d: d.update(inputs=3), r"bad\.json: key 'inputs' must be \['vx_mm_s'"),
])
def test_bad_model_files_name_the_file_and_key(tmp_path, edit, match):
    with pytest.raises(UserError, match=match):
        load_mlp(_bad(tmp_path, edit))


def test_non_finite_and_unreadable_files(tmp_path):
    p = tmp_path / "nan.json"
    p.write_text(THESIS_MODEL.read_text().replace("0.11", "NaN", 1))
    with pytest.raises(UserError, match=r"nan\.json: weights: key .output_bias. is not a finite"):
        load_mlp(p)
    (tmp_path / "trunc.json").write_text(THESIS_MODEL.read_text()[:100])
    with pytest.raises(UserError, match=r"trunc\.json: not a readable JSON model"):
        load_mlp(tmp_path / "trunc.json")
    with pytest.raises(UserError, match=r"absent\.json: missing"):
        load_mlp(tmp_path / "absent.json")


def test_audio_channel_at_the_sound_card_rate_is_the_network_signal(fitted):
    """render("audio") of a 48 kHz finger stream: the 1 kHz render, resampled."""
    from fydpad.texture.families.mlp.render import MlpTexture
    from fydpad.texture.family import finger_from_scan, resample_finger

    scans, model, _ = fitted
    fb = finger_from_scan(scans[1])
    y1k = MlpTexture(model).render(fb, "vibration")
    fb48 = resample_finger(fb, 48_000.0)
    y48 = MlpTexture(model).render(fb48, "audio")
    assert y48.size == fb48.t_s.size
    mid = slice(200, y1k.size - 200)
    np.testing.assert_allclose(y48[::48][mid], y1k[mid], atol=0.02 * np.std(y1k))
    with pytest.raises(UserError, match="renders vibration, audio; not 'tension'"):
        MlpTexture(model).render(fb, "tension")


def test_missing_speed_or_force_fails_safe(fitted):
    """NaN speed: silence; NaN force: the last reading held. Block and tick agree."""
    from fydpad.texture.families.mlp.render import MlpTexture
    from fydpad.texture.family import FingerBlock, finger_from_scan

    scans, model, _ = fitted
    fb = finger_from_scan(scans[1])
    v, f = fb.speed_mm_s.copy(), fb.force_n.copy()
    v[500:520] = np.nan
    f[800:900] = np.nan
    bad = FingerBlock(fb.fs_hz, fb.t_s, fb.contact, fb.x_mm, fb.y_mm, v, f)
    fam = MlpTexture(model)
    block = fam.render(bad)
    assert np.isfinite(block).all() and np.all(block[500:520] == 0.0)
    assert np.std(block[1000:]) > 0  # and it carries on
    fam.reset()
    ticks = [fam.tick(bad.t_s[k], True, bad.x_mm[k], 0.0, v[k], f[k])[0]
             for k in range(v.size)]
    np.testing.assert_allclose(ticks, block, rtol=1e-9, atol=1e-12)
