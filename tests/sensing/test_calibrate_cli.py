"""`fydpad calibrate ir` and `fydpad calibrate force` end to end, and their one-line
errors naming the file, line or column."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from fydpad import cli
from vision.config import G_M_S2, ForceConfig, IRConfig
from vision.indentation import sensor_distances_mm
from vision.ir import distance_to_voltage_v


def write_ir_csv(path: Path, scale=(1.0, 1.04, 0.96), noise_v=0.003, seed=0) -> None:
    """Three sensors whose true curves differ from eq. (1): each reads the paper's
    voltage at ``scale`` times the distance."""
    rng = np.random.default_rng(seed)
    d = np.repeat(np.arange(45.0, 281.0, 5.0), 2)
    v = distance_to_voltage_v(d[:, None] * np.asarray(scale)[None, :])
    v += rng.normal(0, noise_v, v.shape)
    rows = ["# flat target above the sensors, 2 readings per distance", "distance_mm,v0,v1,v2"]
    rows += [f"{a:g},{b:.4f},{c:.4f},{e:.4f}" for a, (b, c, e) in zip(d, v, strict=True)]
    path.write_text("\n".join(rows) + "\n")


def test_calibrate_ir_refits_each_sensor(tmp_path: Path, capsys):
    data, out = tmp_path / "ir.csv", tmp_path / "ir.toml"
    write_ir_csv(data)
    rc = cli.main(["calibrate", "ir", str(data), "--out", str(out), "--plot",
                   str(tmp_path / "ir.png")])
    assert rc == 0
    text = capsys.readouterr().out
    assert text.count("R^2") == 3
    section = tomllib.loads(out.read_text())["ir"]
    cfg = IRConfig(poly_cm=tuple(map(tuple, section["poly_cm"])),
                   valid_range_v=tuple(map(tuple, section["valid_range_v"])))
    # The refitted curves read each sensor's true distance back; the paper's does not.
    d_true = np.linspace(60.0, 200.0, 30)
    for i, s in enumerate((1.0, 1.04, 0.96)):
        v = np.zeros((30, 3)) + 1.3
        v[:, i] = distance_to_voltage_v(d_true * s)
        fitted, _ = sensor_distances_mm(v, cfg.poly_cm, cfg.valid_range_v)
        paper, _ = sensor_distances_mm(v)
        assert np.max(np.abs(fitted[:, i] - d_true)) < 2.5
        if s != 1.0:
            assert np.max(np.abs(paper[:, i] - d_true)) > 5.0
    assert (tmp_path / "ir.png").stat().st_size > 10_000
    # The file is a device configuration the project's loader reads back.
    from fydpad.config import load_config

    loaded = load_config(out)
    if hasattr(loaded, "ir"):
        assert loaded.ir.poly_cm == cfg.poly_cm
        assert loaded.ir.valid_range_v == cfg.valid_range_v


def test_calibrate_ir_one_sensor_keeps_the_others(tmp_path: Path):
    data, out = tmp_path / "ir.csv", tmp_path / "ir.toml"
    d = np.linspace(45, 280, 20)
    v = distance_to_voltage_v(d)
    data.write_text("distance_mm,v1\n" + "".join(f"{a},{b}\n" for a, b in zip(d, v,
                                                                             strict=True)))
    assert cli.main(["calibrate", "ir", str(data), "--out", str(out)]) == 0
    section = tomllib.loads(out.read_text())["ir"]
    assert section["poly_cm"][0] == list(IRConfig().poly_cm[0])
    assert section["valid_range_v"][1] == pytest.approx([v.min(), v.max()])


def _ir_case(path: Path, case: str) -> str:
    d = np.linspace(45, 280, 20)
    v = distance_to_voltage_v(d)
    rows = [f"{a:g},{b:.4f}" for a, b in zip(d, v, strict=True)]
    if case == "too few":
        rows = rows[:5]
        expect = "column 'v0': 5 points, need at least 8"
    elif case == "constant":
        rows = [f"{a:g},1.3000" for a in d]
        expect = "column 'v0': voltage nearly constant"
    elif case == "not a number":
        rows[6] = "80,abc"
        expect = "line 9: column 'v0': 'abc' is not a number"
    elif case == "negative distance":
        rows[3] = "-5,1.3"
        expect = "line 6: distance_mm must be positive"
    elif case == "no voltage column":
        path.write_text("# c\ndistance_mm,volts\n1,2\n")
        return "no voltage column"
    else:  # voltage beyond the supply
        rows[0] = "45,7.5"
        expect = "line 3: column 'v0': 7.5 V is not a sensor voltage"
    path.write_text("# comment\ndistance_mm,v0\n" + "\n".join(rows) + "\n")
    return expect


@pytest.mark.parametrize("case", ["too few", "constant", "not a number", "negative distance",
                                  "no voltage column", "voltage out of range"])
def test_calibrate_ir_bad_input_is_one_line_naming_file_and_line(tmp_path, capsys, case):
    data = tmp_path / "bad.csv"
    expect = _ir_case(data, case)
    assert cli.main(["calibrate", "ir", str(data)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert str(data) in err and expect in err


def test_calibrate_force_from_known_weights(tmp_path: Path, capsys):
    rng = np.random.default_rng(1)
    masses = np.repeat([0, 100, 200, 500, 700], 4)
    raw = 8000 + masses * 1e-3 * G_M_S2 / 3.6e-6 + rng.normal(0, 25, masses.size)
    data, out = tmp_path / "force.csv", tmp_path / "force.toml"
    data.write_text("mass_g,raw\n" + "".join(f"{m},{r:.0f}\n" for m, r in zip(masses, raw,
                                                                             strict=True)))
    assert cli.main(["calibrate", "force", str(data), "--out", str(out), "--plot",
                     str(tmp_path / "f.png")]) == 0
    assert "R^2" in capsys.readouterr().out
    cfg = ForceConfig(**tomllib.loads(out.read_text())["force"])
    assert cfg.gain_n_per_count == pytest.approx(3.6e-6, rel=2e-3)
    assert cfg.offset_counts == pytest.approx(8000, abs=40)
    assert (tmp_path / "f.png").stat().st_size > 10_000


@pytest.mark.parametrize(("body", "expect"), [
    ("mass_g,raw\n0,100\n100,100\n200,100\n", "do not change"),
    ("mass_g,raw\n0,100\n", "at least 3"),
    ("mass_g,raw\n0,100\n100,200\n1000,300\n", "line 4: mass_g 1000 is outside 0-780 g"),
    ("mass_g,raw\n0,100\n100,\n", "line 3: column 'raw' is empty"),
    ("mass,raw\n0,100\n", "missing column(s) mass_g"),
])
def test_calibrate_force_bad_input(tmp_path, capsys, body, expect):
    data = tmp_path / "bad.csv"
    data.write_text(body)
    assert cli.main(["calibrate", "force", str(data)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(data) in err and expect in err


def test_calibrate_lists_its_subcommands(capsys):
    with pytest.raises(SystemExit):
        cli.main(["calibrate", "--help"])
    out = capsys.readouterr().out
    assert "ir" in out and "force" in out


def test_calibrate_indentation_fits_the_correction_from_recordings(tmp_path: Path, capsys):
    from tests.sensing.fabric_model import (
        MembraneFabric,
        random_presses,
        synth_ir,
        write_press_recording,
    )
    from vision.indentation import IndentationEstimator, rmse

    rng = np.random.default_rng(7)
    recs = [tmp_path / "a", tmp_path / "b"]
    for r in recs:
        write_press_recording(r, rng, n_presses=40)
    out = tmp_path / "ir.toml"
    assert cli.main(["calibrate", "indentation", *map(str, recs), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "RMSE against the true depth: plane" in text
    section = tomllib.loads(out.read_text())["ir"]
    assert section["correction_per_sensor"] is True
    cfg = IRConfig(correction_coef=tuple(section["correction_coef"]),
                   correction_xy_degree=section["correction_xy_degree"],
                   correction_depth_degree=section["correction_depth_degree"],
                   baseline_mm=(99.0, 101.0, 100.5))
    # Scored on new presses, never seen by the fit.
    x, y, d = random_presses(2000, rng)
    v = synth_ir(MembraneFabric(), x, y, d, rng, (99.0, 101.0, 100.5))
    corrected = IndentationEstimator.from_config(cfg).estimate(v, x, y).indentation_mm
    plane = IndentationEstimator(baseline_mm=(99.0, 101.0, 100.5)).estimate(v, x, y)
    assert rmse(corrected, d) <= 3.0
    assert rmse(corrected, d) < 0.8 * rmse(plane.indentation_mm, d)


def test_calibrate_indentation_needs_the_fabric_clear_before_the_first_press(
        tmp_path: Path, capsys):
    """The rest distances come from before the first press (``fydpad track``'s rule): a
    recording that starts pressing is refused, naming its ir.csv, not fitted on the
    wrong rest distances."""
    from tests.sensing.fabric_model import write_press_recording

    recs = [tmp_path / "a", tmp_path / "b"]
    for r in recs:
        write_press_recording(r, np.random.default_rng(3), n_presses=30)
    ir = recs[1] / "ir.csv"
    lines = ir.read_text().splitlines()
    keep = [ln for ln in lines[1:] if float(ln.split(",")[0]) >= 0.42]
    ir.write_text("\n".join([lines[0], *keep]) + "\n")
    assert cli.main(["calibrate", "indentation", *map(str, recs)]) == 2
    err = capsys.readouterr().err
    assert f"{ir}: 2 IR samples before the first press" in err
    assert "start each recording with the fabric clear" in err


def test_calibrate_indentation_needs_truth(tmp_path: Path, capsys):
    from tests.sensing.fabric_model import write_press_recording

    rec = tmp_path / "r"
    write_press_recording(rec, np.random.default_rng(0), n_presses=2)
    assert cli.main(["calibrate", "indentation", str(rec)]) == 2
    assert "the correction needs at least" in capsys.readouterr().err
    (rec / "truth.csv").unlink()
    assert cli.main(["calibrate", "indentation", str(rec)]) == 2
    err = capsys.readouterr().err
    assert "truth.csv: missing" in err and len(err.strip().splitlines()) == 1


def test_calibrate_indentation_protocol_takes_two_minutes_and_covers_the_workspace(capsys):
    """--protocol prints the presses: where (over the whole workspace, edges included)
    and how deep (the slides' and the taps' ranges), in about two minutes of recording;
    without recordings or --protocol the command says what it needs."""
    from fydpad.indentation_protocol import duration_s, presses

    assert cli.main(["calibrate", "indentation", "--protocol"]) == 0
    out = capsys.readouterr().out
    ps = presses()
    assert len(ps) == 36 and 60 <= duration_s() <= 120
    assert f"{ps[0].x_mm:+.0f}" in out and "depth mm" in out and "load cell" in out
    xs, ys = [p.x_mm for p in ps], [p.y_mm for p in ps]
    assert min(xs) < -35 and max(xs) > 35 and min(ys) < -24 and max(ys) > 24
    assert {p.depth_mm for p in ps} == {4.0, 10.0, 20.0, 35.0}
    assert cli.main(["calibrate", "indentation"]) == 2
    assert "--protocol" in capsys.readouterr().err
