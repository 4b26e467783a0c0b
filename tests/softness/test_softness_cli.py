"""``fydpad softness calibrate`` and ``fit-specimen`` end to end through the CLI."""

from __future__ import annotations

import re

import numpy as np
import pytest

from fydpad import cli
from fydpad.softness import load_table


def write_calibration(path, ks=(0.27, 0.5, 0.75, 1.04), thetas=(0.0, 0.4, 0.8, 1.2),
                      column="theta_rad", noise=0.04, seed=0):
    rng = np.random.default_rng(seed)
    rows = [f"# indenter run\n{column},indentation_mm,force_n"]
    for th, k in zip(thetas, ks, strict=True):
        for d in np.linspace(0.5, 10, 15):
            t = np.rad2deg(th) if column == "theta_deg" else th
            rows.append(f"{t:.6f},{d:.4f},{k * d + rng.normal(0, noise):.5f}")
    path.write_text("\n".join(rows) + "\n")
    return path


def test_calibrate_writes_table_and_plot(tmp_path, capsys):
    data = write_calibration(tmp_path / "cal.csv")
    out, png = tmp_path / "table.csv", tmp_path / "cal.png"
    assert cli.main(["softness", "calibrate", str(data), "--out", str(out),
                     "--plot", str(png)]) == 0
    table = load_table(out)
    np.testing.assert_allclose(table.k_n_per_mm, [0.27, 0.5, 0.75, 1.04], rtol=0.02)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = capsys.readouterr().out
    assert "theta = 0.400 rad: k = 0.50" in text and "table written" in text


def test_calibrate_accepts_degrees(tmp_path):
    data = write_calibration(tmp_path / "cal.csv", column="theta_deg")
    out = tmp_path / "table.csv"
    assert cli.main(["softness", "calibrate", str(data), "--out", str(out)]) == 0
    np.testing.assert_allclose(load_table(out).theta_rad, [0.0, 0.4, 0.8, 1.2], atol=1e-6)


def test_poor_fit_warns_but_strict_refuses(tmp_path, capsys):
    data = write_calibration(tmp_path / "cal.csv", noise=1.2, seed=2)
    out = tmp_path / "table.csv"
    assert cli.main(["softness", "calibrate", str(data), "--out", str(out)]) == 0
    assert "warning:" in capsys.readouterr().err
    out.unlink()
    assert cli.main(["softness", "calibrate", str(data), "--out", str(out), "--strict"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cal.csv" in err and "--strict" in err
    assert not out.exists()


@pytest.mark.parametrize("content, expected", [
    ("theta_rad,indentation_mm\n0,1\n", "missing column"),
    ("indentation_mm,force_n\n1,1\n", "theta_rad"),
    ("theta_rad,indentation_mm,force_n\n0,1,1\n0,2,x\n", "line 3"),
    ("theta_rad,indentation_mm,force_n\n0,1,1\n0,2,2\n", "2 or more motor positions"),
])
def test_calibrate_bad_input_is_one_line(tmp_path, capsys, content, expected):
    data = tmp_path / "bad.csv"
    data.write_text(content)
    assert cli.main(["softness", "calibrate", str(data), "--out",
                     str(tmp_path / "t.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and expected in err and "bad.csv" in err


def test_fit_specimen_prints_lambda_and_plots(tmp_path, capsys):
    rng = np.random.default_rng(1)
    d = np.linspace(0.3, 6, 50)
    data = tmp_path / "SS3.csv"
    data.write_text("indentation_mm,force_n\n" + "".join(
        f"{a:.4f},{0.39 * a + rng.normal(0, 0.03):.5f}\n" for a in d))
    png = tmp_path / "s.png"
    assert cli.main(["softness", "fit-specimen", str(data), "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    m = re.match(r"SS3: lambda = ([0-9.]+) N/mm, R\^2 = ([0-9.]+)", out)
    assert m and float(m[1]) == pytest.approx(0.39, rel=0.02) and float(m[2]) > 0.924
    assert "nearest paper specimen SS3" in out
    assert png.stat().st_size > 1000
    assert cli.main(["softness", "fit-specimen", str(data), "--name", "mine"]) == 0
    assert capsys.readouterr().out.startswith("mine: lambda")


def test_fit_specimen_missing_file(tmp_path, capsys):
    assert cli.main(["softness", "fit-specimen", str(tmp_path / "nope.csv")]) == 2
    assert "nope.csv" in capsys.readouterr().err
