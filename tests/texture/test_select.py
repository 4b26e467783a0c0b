"""The plain paper fit and the validated choice of form, on strokes rendered from a
small HaTT-schema model written here (its resonance moves with speed)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fydpad.errors import UserError
from fydpad.synth.texture_scans import hand_speed, penn_scan, plateau_speed
from fydpad.texture.evaluation.evaluate import lsd_db, welch_psd
from fydpad.texture.families import load_family
from fydpad.texture.families.penn.toolkit import PennModelSet
from fydpad.texture.lpc.analysis import ar_psd, levinson, lpc_autocorrelation
from fydpad.texture.lpc.dft321 import preprocess
from fydpad.texture.lpc.fit import fit_paper
from fydpad.texture.lpc.model_file import load_model, model_to_json, save_model
from fydpad.texture.lpc.select import CANDIDATES, CandidateScore, select_model
from fydpad.texture.scan_io import write_scan
from tests.texture.lpc_polys import poly_to_lsf, reflection_to_poly
from tests.texture_families.helpers import run_cli

FS = 1000.0


def _model_set() -> PennModelSet:
    """AR(6) models whose main resonance rises from 80 Hz at rest to 380 Hz at 60 mm/s."""
    def poly(f_hz: float) -> np.ndarray:
        w = 2 * np.pi * f_hz / FS
        return np.convolve([1, -2 * 0.95 * np.cos(w), 0.95**2], reflection_to_poly([0.4, -0.3,
                                                                                    0.2, 0.1]))
    speeds = np.array([0.0, 60.0, 0.0, 60.0])
    forces = np.array([0.5, 0.5, 3.0, 3.0])
    ar = np.vstack([poly_to_lsf(poly(f)) for f in (80.0, 380.0, 80.0, 380.0)])
    return PennModelSet("ridged", FS, speeds, forces, np.array([[0, 1, 2], [1, 3, 2]]), ar,
                        np.zeros((4, 0)), np.array([0.01, 0.04, 0.02, 0.08]), np.ones(4),
                        60.0, 3.0)


@pytest.fixture(scope="module")
def stroke():
    rng = np.random.default_rng(3)
    return penn_scan(_model_set(), plateau_speed((10, 20, 30, 40), 30.0, FS, rng), seed=3)


def test_autocorrelation_of_a_segment_shorter_than_the_lags():
    x, y = np.split(np.random.default_rng(0).standard_normal(150), [50])
    r = np.zeros(81)
    r[:50] = np.correlate(x, x, "full")[49:]  # no wrapped lags above 49
    r += np.correlate(y, y, "full")[99:180]
    r /= 150
    r[0] *= 1.0 + 1e-9
    want_a, want_s2 = levinson(r, 80)
    a, s2 = lpc_autocorrelation([x, y], 80)
    np.testing.assert_allclose(a, want_a, atol=1e-9)
    assert s2 == pytest.approx(want_s2, rel=1e-9)


def test_plain_fit_is_each_speeds_window(stroke):
    model = fit_paper([stroke], order=60)
    assert model.interpolation == "nearest"
    assert np.allclose(np.diff(model.speeds_mm_s), 1.0)
    x = preprocess(stroke.acc, FS, 10.0)
    for v in (20.0, 30.0):
        i = int(np.argmin(np.abs(model.speeds_mm_s - v)))
        mask = np.abs(stroke.speed_mm_s - v) <= 5.0
        f, p = welch_psd(x, FS, mask)
        band = (f >= 20) & (f <= 480)
        pm = ar_psd(model.poly(i), model.sigma2[i], f, FS)
        # the window's own spectrum, against its order-60 all-pole fit: measured 0.9-1.0 dB
        assert lsd_db(p[band], pm[band]) < 1.5


def test_validation_chooses_and_records(stroke, tmp_path):
    model, sel = select_model([stroke], order=60)
    assert sel.validated and [c.name for c in sel.candidates] == list(CANDIDATES)
    best = min(c.mean_lsd_db for c in sel.candidates)
    chosen = next(c for c in sel.candidates if c.name == sel.winner)
    assert chosen.mean_lsd_db - best <= sel.noise_db[sel.winner]
    for c in sel.candidates:  # two block folds x 4 plateaus; 20 and 30 held out whole
        assert len(c.block_lsd_db) == 8 and len(c.between_lsd_db) == 2
        assert np.isfinite(c.scores).all() and (c.scores > 0).all()
    assert model.interpolation == ("nearest" if sel.winner == "paper" else "stretch")
    back = load_model(save_model(model, tmp_path / "m.json"))
    assert back.selection["winner"] == sel.winner
    assert back.interpolation == model.interpolation


def test_one_plateau_cannot_validate():
    rng = np.random.default_rng(4)
    scan = penn_scan(_model_set(), hand_speed(20.0, 8.0, FS, rng), seed=4)
    model, sel = select_model([scan], order=60)
    assert not sel.validated and sel.winner == "paper" and "cannot validate" in sel.reason
    assert model.interpolation == "nearest"


def test_removed_interpolation_fails_in_one_line(stroke, tmp_path):
    data = model_to_json(fit_paper([stroke], order=20))
    data["interpolation"] = "spline"
    path = tmp_path / "old.json"
    path.write_text(json.dumps(data))
    with pytest.raises(UserError, match=r"old\.json: key 'interpolation' 'spline'.*refit"):
        load_model(path)


def test_model_json_is_strict(stroke, tmp_path):
    model = fit_paper([stroke], order=20)
    model.selection = {"winner": "paper", "mean_lsd_db": float("nan")}
    with pytest.raises(UserError, match=r"nan\.json: the model holds a non-finite number"):
        save_model(model, tmp_path / "nan.json")
    assert not (tmp_path / "nan.json").exists()


def test_cli_fit_validates_and_synth_uses_the_models_interpolation(stroke, tmp_path, capsys):
    scan = write_scan(tmp_path / "train.csv", stroke.t_s, stroke.acc, stroke.speed_mm_s,
                      meta={"surface": "ridged"})
    out = tmp_path / "m.json"
    plot = tmp_path / "fit.png"
    assert run_cli("fit", str(scan), "--out", str(out), "--order", "40",
                   "--form", "paper", "--plot", str(plot)) == 0
    assert plot.stat().st_size > 10_000
    text = capsys.readouterr().out
    assert "form paper" in text and "interpolation nearest" in text
    assert json.loads(out.read_text())["interpolation"] == "nearest"
    syn = tmp_path / "s.csv"
    assert run_cli("synth", str(out), "--speed-mm-s", "25", "--seconds", "1",
                   "--out", str(syn)) == 0
    assert len(syn.read_text().splitlines()) > 900
    fam = load_family(str(out))  # what synth and the station render: the file's own
    fam.prepare(fam.model.fs_hz)
    assert fam.tick_renderer.interpolation == "nearest"


def test_between_blocks_weigh_as_much_as_the_time_blocks():
    """8 time blocks and 2 between-plateau blocks: each kind is half the score."""
    c = CandidateScore("paper", [1.0] * 8, [3.0, 5.0])
    assert c.mean_lsd_db == pytest.approx(0.5 * 1.0 + 0.5 * 4.0)
    assert CandidateScore("paper", [1.0, 2.0], []).mean_lsd_db == pytest.approx(1.5)
