"""``fydpad texture`` end to end on generated scans (parser registered as the CLI does)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fydpad.errors import UserError
from tests.texture_families.helpers import run_cli
from vision.recording import read_csv_columns

run = run_cli  # ``fydpad texture ...`` in this process


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    assert run("generate-scans", "--out-dir", str(d), "--textures", "R1,felt",
               "--speeds", "10,30", "--strokes", "1", "--seconds", "4") == 0
    for name in ("R1", "felt"):
        assert run("fit", str(d / f"{name}_10mms_s1.csv"), str(d / f"{name}_30mms_s1.csv"),
                   "--out", str(d / f"{name}.json"), "--speeds", "10,30", "--order", "100",
                   "--form", "calibrated", "--plot", str(d / f"{name}_fit.png")) == 0
    return d


def test_fit_writes_documented_model_and_plot(workdir):
    """The documented keys (docs/texture_model_format.md), for a grating (R1) as for
    random roughness (felt), and the fit's plot."""
    for name in ("R1", "felt"):
        m = json.loads((workdir / f"{name}.json").read_text())
        assert m["format_version"] == 1 and m["sample_rate_hz"] == 1000.0
        assert [x["speed_mm_s"] for x in m["models"]] == [10.0, 30.0]
        assert m["drive_band_hz"] == [165.0, 220.0] and m["provenance"]["scans"]
        assert m["interpolation"] == "stretch" and m["provenance"]["form"] == "calibrated"
        assert (workdir / f"{name}_fit.png").stat().st_size > 1000


def test_synth_writes_t_a_at_1khz(workdir, tmp_path):
    out = tmp_path / "a.csv"
    assert run("synth", str(workdir / "R1.json"), "--speed-mm-s", "20", "--seconds", "0.5",
               "--out", str(out)) == 0
    cols = read_csv_columns(out, ("t_s", "a"))
    assert cols["t_s"].size == 500 and np.allclose(np.diff(cols["t_s"]), 1e-3)
    assert np.std(cols["a"]) > 0


def test_evaluate_and_identify_json(workdir, tmp_path):
    ej = tmp_path / "e.json"
    assert run("evaluate", str(workdir / "R1.json"), str(workdir / "R1_30mms_s1.csv"),
               "--json", str(ej), "--plot", str(tmp_path / "e.png")) == 0
    e = json.loads(ej.read_text())
    assert {"psd_correlation", "lsd_db", "time_correlation", "band_energy_recorded"} <= set(e)
    ij = tmp_path / "i.json"
    assert run("identify", str(workdir / "R1.json"), str(workdir / "felt.json"), "--scans",
               str(workdir / "R1_10mms_s1.csv"), str(workdir / "felt_30mms_s1.csv"),
               "--json", str(ij), "--plot", str(tmp_path / "i.png")) == 0
    i = json.loads(ij.read_text())
    assert i["labels"] == ["R1", "felt"] and np.array(i["confusion"]).sum() == 2
    assert 0.0 <= i["rate"] <= 1.0


def test_bad_input_is_a_user_error(workdir, tmp_path):
    bad = tmp_path / "m.json"
    m = json.loads((workdir / "R1.json").read_text())
    m["format_version"] = 3
    bad.write_text(json.dumps(m))
    with pytest.raises(UserError, match="format_version"):
        run("synth", str(bad), "--speed-mm-s", "20", "--seconds", "1", "--out",
            str(tmp_path / "x.csv"))
    with pytest.raises(UserError, match="unknown nope"):
        run("generate-scans", "--out-dir", str(tmp_path), "--textures", "nope")
    with pytest.raises(UserError, match="--load-scale"):
        run("generate-scans", "--out-dir", str(tmp_path), "--load-scale", "0")
    short = tmp_path / "short.csv"
    short.write_text("t_s,ax,ay,az,speed_mm_s\n" + "".join(
        f"{k / 1000:.3f},0.1,0.2,{k % 3},20\n" for k in range(300)))
    with pytest.raises(UserError, match="order-200"):
        run("fit", str(short), "--out", str(tmp_path / "s.json"), "--speeds", "20",
            "--form", "calibrated")


def test_generate_scans_list_needs_no_out_dir(tmp_path, capsys, monkeypatch):
    from fydpad.synth.texture_scans import TEXTURES

    monkeypatch.chdir(tmp_path)
    assert run("generate-scans", "--list") == 0
    listed = [line.split()[0] for line in capsys.readouterr().out.splitlines()]
    assert listed == list(TEXTURES) and "R1" in listed
    assert list(tmp_path.iterdir()) == []  # nothing written
    with pytest.raises(UserError, match="--out-dir"):
        run("generate-scans", "--textures", "R1")


def test_evaluate_refuses_a_scan_outside_the_models_speeds(workdir, tmp_path):
    fast = tmp_path / "fast.csv"
    fast.write_text("# surface=R1\nt_s,ax,ay,az,speed_mm_s\n" + "".join(
        f"{k / 1000:.3f},0.1,0.2,{k % 3},80\n" for k in range(3000)))
    with pytest.raises(UserError, match=r"fast\.csv: column 'speed_mm_s'"):
        run("evaluate", str(workdir / "R1.json"), str(fast))


def test_fit_warns_when_the_scans_are_of_several_surfaces(workdir, tmp_path, capsys):
    """Scans labelled R1 and felt (`# surface=`) pooled into one model: said once, on one
    line; --surface names the mix and silences it."""
    scans = [str(workdir / "R1_10mms_s1.csv"), str(workdir / "felt_30mms_s1.csv")]
    assert run("fit", *scans, "--out", str(tmp_path / "mix.json"), "--speeds", "10,30",
               "--order", "60", "--form", "calibrated") == 0
    err = [ln for ln in capsys.readouterr().err.splitlines() if "surfaces" in ln]
    assert err == ["fydpad texture fit: warning: the scans are of 2 surfaces (# surface=: R1 "
                   "(1), felt (1)), pooled into one model labelled R1; fit each surface on its "
                   "own, or name the mix with --surface"]
    assert run("fit", *scans, "--out", str(tmp_path / "mix.json"), "--speeds", "10,30",
               "--order", "60", "--form", "calibrated", "--surface", "R1+felt") == 0
    assert "surfaces" not in capsys.readouterr().err


def test_generate_scans_with_a_light_touch_writes_that_stroke_and_says_so(tmp_path):
    """--load-scale 0.3 writes the generator's light-touch stroke (the physics is tested in
    test_generator.py: brick at 35 mm/s is then off the surface a fifth of the time) and
    the file's header says which load it was scanned with."""
    from fydpad.synth.texture_scans import generate_scan
    from fydpad.texture.scan_io import read_scan

    for scale, sub in (("1", "own"), ("0.3", "light")):
        assert run("generate-scans", "--out-dir", str(tmp_path / sub), "--textures", "brick",
                   "--speeds", "35", "--strokes", "1", "--seconds", "3",
                   "--load-scale", scale) == 0
    own = read_scan(tmp_path / "own" / "brick_35mms_s1.csv")
    light = read_scan(tmp_path / "light" / "brick_35mms_s1.csv")
    assert light.meta.get("load_scale") == "0.3" and "load_scale" not in own.meta
    expected = generate_scan("brick", 35.0, 3.0, seed=1, load_scale=0.3)
    assert expected.in_flight_share > 0.1
    np.testing.assert_allclose(light.acc, expected.acc, atol=1e-5)
    assert np.abs(light.acc[:, 2] - own.acc[:, 2]).max() > 1.0  # m/s^2: impacts differ
