"""Indentation against the synthetic pad (``fydpad.synth``): its fabric model (not a
plane), its IR sensors (their own 16.5 ms measurement period, 6 mV noise, mounting
spread of +-1.5 mm, 10-bit ADC) and its tapping trajectory (15-45 mm deep at random
places). The correction is always scored on sessions it was not fitted on."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fydpad import cli
from fydpad.synth import SynthConfig, SyntheticPad
from vision.config import IRConfig
from vision.indentation import (
    IndentationEstimator,
    SagCorrection,
    indentation_at_frames,
    rmse,
)
from vision.recording import PadRecording


def press_numbers(contact: np.ndarray) -> np.ndarray:
    return np.cumsum(np.diff(np.concatenate([[0], contact.astype(int)])) == 1)


def session(seed: int, seconds: float = 60.0) -> dict[str, np.ndarray]:
    """A tapping session's plane estimates at the truth's frames (no video rendered)."""
    pad = SyntheticPad(SynthConfig(trajectory="tapping", seconds=seconds, seed=seed))
    t_ir, volts = pad.ir()
    truth = [pad.truth(k) for k in range(pad.frame_count)]
    t = np.array([tr.t_s for tr in truth])
    c = np.array([tr.contact for tr in truth])
    x = np.array([tr.x_mm for tr in truth])
    y = np.array([tr.y_mm for tr in truth])
    d = np.array([tr.indentation_mm for tr in truth])
    meta = pad.meta()
    est = IndentationEstimator.from_config(IRConfig(), sensors_mm=meta.ir_sensors_mm,
                                           base_to_fabric_mm=meta.base_to_fabric_mm)
    r, used = indentation_at_frames(est, t_ir, volts, t, c, x, y)
    k = c & r.valid
    return {"plane": r.plane_mm[k], "e": r.deflection_mm[k], "x": x[k], "y": y[k],
            "depth": d[k],
            "press": press_numbers(c)[k] + 1000 * seed, "all_valid": r.valid[c].all(),
            "rest_true": pad.ir_rest_mm, "rest_used": np.asarray(used.baseline_mm)}


def test_indentation_on_the_synthetic_pad():
    cal = [session(11), session(12)]
    test = session(13)
    for s in (*cal, test):
        assert s["all_valid"]
        # Rest distances from the samples before the first tap, finer than an ADC step.
        np.testing.assert_allclose(s["rest_used"], s["rest_true"], atol=0.15)
    data = {k: np.concatenate([s[k] for s in cal]) for k in ("e", "x", "y", "depth",
                                                             "press")}
    corr, _, _ = SagCorrection.fit_cv(data["e"], data["x"], data["y"], data["depth"],
                                      data["press"])
    d = test["depth"]
    assert d.max() > 40.0
    plane_rmse = rmse(test["plane"], d)
    corrected_rmse = rmse(corr.apply(test["e"], test["x"], test["y"]), d)
    print(f"seed 13, fitted on seeds 11 and 12: plane {plane_rmse:.2f} mm, corrected "
          f"{corrected_rmse:.2f} mm")
    # The plane alone is 2-3.4 mm on such sessions (paper: 2.88 mm); the corrected
    # estimate is the one held to the target.
    assert plane_rmse > 2.0
    assert corrected_rmse <= 3.0
    assert corrected_rmse < 0.8 * plane_rmse
    deep = d > 30.0
    assert rmse(corr.apply(test["e"][deep], test["x"][deep], test["y"][deep]),
                d[deep]) < rmse(test["plane"][deep], d[deep])


def write_session(path: Path, seed: int, seconds: float = 60.0) -> Path:
    # Small frames at the paper's 10 Hz tracker rate: only ir.csv and truth.csv matter.
    cfg = SynthConfig(trajectory="tapping", seconds=seconds, seed=seed, frame_size=(80, 60),
                      roi_px=(3, 3, 74, 52), fps=10.0)
    return SyntheticPad(cfg).write(path)


def test_calibrate_indentation_on_synthetic_recordings(tmp_path: Path, capsys):
    """End to end through the files: two recordings calibrate, a third one scores."""
    recs = [write_session(tmp_path / f"cal{seed}", seed) for seed in (21, 22)]
    out = tmp_path / "device.toml"
    assert cli.main(["calibrate", "indentation", *map(str, recs), "--out", str(out)]) == 0
    assert "held-out presses" in capsys.readouterr().out
    from fydpad.config import load_config

    ir_config = load_config(out).ir
    assert ir_config.correction_coef
    rec = PadRecording(write_session(tmp_path / "test", 23))
    t_ir, volts = rec.read_ir()
    truth = rec.read_truth()
    scores = {}
    for name, cfg in (("plane", IRConfig()), ("corrected", ir_config)):
        est = IndentationEstimator.from_config(cfg, sensors_mm=rec.meta.ir_sensors_mm,
                                               base_to_fabric_mm=rec.meta.base_to_fabric_mm)
        r, _ = indentation_at_frames(est, t_ir, volts, truth.t_s, truth.contact,
                                     truth.x_mm, truth.y_mm)
        c = truth.contact
        assert r.valid[c].all()
        assert np.all(r.indentation_mm[~c] == 0.0)
        scores[name] = rmse(r.indentation_mm[c], truth.indentation_mm[c])
    print("end to end through the files, RMSE mm:", scores)
    assert scores["corrected"] <= 3.0
    assert scores["corrected"] < 0.85 * scores["plane"]


@pytest.mark.parametrize("trajectory", ["circle", "walk"])
def test_light_presses_of_the_other_trajectories(trajectory):
    """Sliding at 2-20 mm deep: the plane alone, no correction, within the target."""
    pad = SyntheticPad(SynthConfig(trajectory=trajectory, seconds=20.0, seed=5))
    t_ir, volts = pad.ir()
    truth = [pad.truth(k) for k in range(pad.frame_count)]
    c = np.array([tr.contact for tr in truth])
    r, _ = indentation_at_frames(
        IndentationEstimator(), t_ir, volts, np.array([tr.t_s for tr in truth]), c,
        np.array([tr.x_mm for tr in truth]), np.array([tr.y_mm for tr in truth]))
    d = np.array([tr.indentation_mm for tr in truth])
    assert c.sum() > 100 and r.valid[c].all()
    assert rmse(r.indentation_mm[c], d[c]) <= 3.0
