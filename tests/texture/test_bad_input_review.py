"""Bad input: a model at another rate, malformed model
headers, unchecked fit options, unwritable outputs, a scan too short to identify, scan
line numbers, fit warnings and a non-finite speed. Each error one line naming the file
and the key, option or line."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from fydpad.errors import UserError
from fydpad.station.texture_source import open_texture
from fydpad.synth.texture_scans import generate_scan, save_generated
from fydpad.texture.lpc.family import LpcFamily
from fydpad.texture.lpc.model_file import TextureModel, load_model, model_to_json
from fydpad.texture.lpc.synthesis import TextureRenderer
from fydpad.texture.scan_io import read_scan
from tests.texture_families.helpers import run_cli
from vision.recording import RecordingError

run = run_cli  # ``fydpad texture ...`` in this process


def _model(fs_hz: float = 1000.0, surface: str = "R1") -> TextureModel:
    """A small stable two-speed model (order 2), no fit needed."""
    return TextureModel(surface=surface, fs_hz=fs_hz, speeds_mm_s=np.array([10.0, 30.0]),
                        h=np.array([[0.5, -0.2], [0.4, -0.1]]),
                        sigma2=np.array([1e-3, 2e-3]), fit_band_hz=(10.0, fs_hz / 2))


def _save(data: dict, path) -> str:
    path.write_text(json.dumps(data))
    return str(path)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("review")
    for s in (10.0, 30.0):
        save_generated(generate_scan("R1", s, 2.0, seed=1), d / f"R1_{s:g}.csv")
    save_generated(generate_scan("R1", 20.0, 0.2, seed=1), d / "tiny.csv")  # 200 rows
    _save(model_to_json(_model()), d / "R1.json")
    _save(model_to_json(_model(surface="R2")), d / "R2.json")
    _save(model_to_json(_model(2000.0)), d / "R1_2k.json")
    return d


# ---------------------------------------------------------------- 2: sample rate
def test_texture_source_refuses_a_model_at_another_rate(files):
    m2k = str(files / "R1_2k.json")
    with pytest.raises(UserError, match=r"R1_2k\.json: key 'sample_rate_hz' is 2000 Hz.*1000"):
        open_texture(m2k, 1000.0)
    with pytest.raises(UserError, match="sample_rate_hz"):
        LpcFamily(load_model(m2k)).prepare(1000.0)
    open_texture(str(files / "R1.json"), 1000.0)  # the station's own rate renders


def test_run_refuses_a_model_at_another_rate_before_the_station_starts(files, capsys,
                                                                       monkeypatch):
    import fydpad.station.station as station_module
    from fydpad.cli import main

    def station(*a, **k):
        raise AssertionError("the station was built before the model was checked")

    # `fydpad run` imports the Station from its module when it runs.
    monkeypatch.setattr(station_module, "Station", station)
    m2k = str(files / "R1_2k.json")
    # Old: the station ran 0.2 s at the wrong pitch, rc 0.
    assert main(["run", "--synthetic", "circle", "--motors", "sim", "--texture", m2k,
                 "--duration", "0.2", "--as-fast-as-possible", "--no-realtime"]) == 2
    err = capsys.readouterr().err
    assert "R1_2k.json: key 'sample_rate_hz' is 2000 Hz" in err and err.count("\n") == 1


def test_identify_refuses_a_model_at_another_rate(files):
    with pytest.raises(UserError, match=r"R1_10\.csv: column 't_s': sample rate 1000 Hz, "
                       r".*R1_2k\.json: key 'sample_rate_hz' 2000 Hz"):
        run("identify", str(files / "R1_2k.json"), str(files / "R2.json"),
            "--scans", str(files / "R1_10.csv"))


# ---------------------------------------------------------------- 3: model header
@pytest.mark.parametrize("key, value, match", [
    ("sample_rate_hz", "fast", "key 'sample_rate_hz' must be a finite number > 0"),
    ("sample_rate_hz", 0, "key 'sample_rate_hz' must be a finite number > 0"),
    ("gain", "loud", "key 'gain' must be a finite number >= 0"),
    ("gain", -2, "key 'gain' must be a finite number >= 0"),
    ("drive_band_hz", "x", r"key 'drive_band_hz' must be \[lo, hi\]"),
    ("drive_band_hz", [220, 165], r"key 'drive_band_hz' must be \[lo, hi\]"),
    ("drive_band_hz", [100, 600], r"key 'drive_band_hz' .* < 500 Hz"),
    ("fit_band_hz", "x", r"key 'fit_band_hz' must be \[lo, hi\]"),
    ("highpass_hz", None, "key 'highpass_hz' must be a finite number >= 0"),
    ("highpass_hz", 600, "key 'highpass_hz' 600 Hz must be below the Nyquist"),
    ("provenance", 5, "key 'provenance' must be an object"),
    ("speed_tolerance_mm_s", -1, "key 'speed_tolerance_mm_s' must be a finite number >= 0"),
    ("order", 3, "key 'order' is 3, but models\\[\\].h have 2 coefficients"),
    ("models.speed_mm_s", -20, r"models\[1\]: key 'speed_mm_s' must be a finite number > 0 "
     "mm/s, not -20"),
    ("models.sigma2", 0, r"models\[1\]: key 'sigma2' must be a finite number > 0"),
    ("models.h", 3, r"models\[1\]: key 'h' must be a non-empty list of finite numbers"),
    ("models", [{}, 3], r"models\[0\]: missing key 'speed_mm_s'"),
    ("models", [3], r"models\[0\] must be an object, not 3"),
])
def test_model_header_is_checked_naming_the_key(tmp_path, key, value, match):
    data = model_to_json(_model())
    if key.startswith("models."):
        data["models"][1][key.split(".")[1]] = value
    else:
        data[key] = value
    path = _save(data, tmp_path / "bad.json")
    with pytest.raises(UserError, match=rf"bad\.json: {match}") as exc:
        load_model(path)
    assert "\n" not in str(exc.value)


def test_model_header_defaults_and_null_drive_band_still_read(tmp_path):
    data = model_to_json(_model())
    for k in ("order", "highpass_hz", "fit_band_hz", "gain", "speed_tolerance_mm_s",
              "provenance"):
        del data[k]
    data["drive_band_hz"] = None
    m = load_model(_save(data, tmp_path / "ok.json"))
    assert (m.highpass_hz, m.fit_band_hz, m.drive_band_hz, m.gain, m.tolerance_mm_s) == (
        10.0, (10.0, 500.0), None, 1.0, 5.0)


# ---------------------------------------------------------------- 4: fit options
@pytest.mark.parametrize("option, value, match", [
    ("--highpass-hz", "600", "--highpass-hz 600: must be >= 0 and below the scans' Nyquist "
     "frequency 500 Hz"),
    ("--drive-band", "300,600", "--drive-band 300,600: need 0 < LO < HI < the scans' Nyquist"),
    ("--drive-band", "220,165", "--drive-band 220,165: need 0 < LO < HI"),
    ("--drive-band", "0,100", "--drive-band 0,100: need 0 < LO"),
])
def test_fit_options_checked_against_the_scans(files, tmp_path, option, value, match):
    with pytest.raises(UserError, match=match):
        run("fit", str(files / "R1_10.csv"), "--out", str(tmp_path / "m.json"),
            "--speeds", "10", "--order", "10", "--form", "calibrated", option, value)
    assert not (tmp_path / "m.json").exists()


# ---------------------------------------------------------------- 5: outputs
@pytest.mark.parametrize("argv, option", [
    (("fit", "{d}/R1_10.csv", "--speeds", "10", "--order", "10", "--out", "{t}/no/m.json"),
     "--out"),
    (("fit", "{d}/R1_10.csv", "--speeds", "10", "--order", "10", "--out", "{t}/m.json",
      "--plot", "{t}/no/p.png"), "--plot"),
    (("synth", "{d}/R1.json", "--speed-mm-s", "20", "--seconds", "0.2", "--out",
      "{t}/no/a.csv"), "--out"),
    (("evaluate", "{d}/R1.json", "{d}/R1_10.csv", "--json", "{t}/no/e.json"), "--json"),
    (("evaluate", "{d}/R1.json", "{d}/R1_10.csv", "--plot", "{t}/no/e.png"), "--plot"),
    (("identify", "{d}/R1.json", "{d}/R2.json", "--scans", "{d}/R1_10.csv", "--json",
      "{t}/no/i.json"), "--json"),
    (("identify", "{d}/R1.json", "{d}/R2.json", "--scans", "{d}/R1_10.csv", "--plot",
      "{t}/no/i.png"), "--plot"),
])
def test_output_in_a_missing_directory_fails_before_the_work(files, tmp_path, monkeypatch,
                                                             argv, option):
    import fydpad.texture.lpc.select as select
    import fydpad.texture.lpc.synthesis as syn
    import fydpad.texture.operations as ops

    def started(*a, **k):
        raise AssertionError("the work started before the output was checked")

    monkeypatch.setattr(select, "fit_texture", started)  # the names fit calls them by
    monkeypatch.setattr(select, "fit_paper", started)
    monkeypatch.setattr(ops, "evaluate_model", started)
    monkeypatch.setattr(ops, "identify_models", started)
    monkeypatch.setattr(syn, "TextureRenderer", started)
    args = [a.format(d=files, t=tmp_path) for a in argv]
    missing = tmp_path / "no"
    with pytest.raises(UserError, match=rf"{option} {missing}/\S+: directory {missing} does "
                       "not exist"):
        run(*args)


# ---------------------------------------------------------------- 6: short scan
def test_identify_names_a_scan_too_short(files):
    with pytest.raises(UserError, match=r"tiny\.csv: too short to identify \(200 rows"):
        run("identify", str(files / "R1.json"), str(files / "R2.json"),
            "--scans", str(files / "tiny.csv"))


# ---------------------------------------------------------------- 8: line numbers
def _scan_text(comment: bool, blank_after: int | None = None) -> str:
    rows = [f"{k * 0.001:.3f},0,0,1,20" for k in range(50)]
    rows[20] = rows[19]  # row 20 repeats row 19's time
    if blank_after is not None:
        rows.insert(blank_after + 1, "")
    head = ["# surface=test"] if comment else []
    return "\n".join([*head, "t_s,ax,ay,az,speed_mm_s", *rows]) + "\n"


@pytest.mark.parametrize("comment, blank_after, line", [
    (True, None, 23),  # comment line 1, header 2, row 0 on line 3: row 20 on line 23
    (False, None, 22),
    (True, 5, 24),  # a blank line skipped by the reader still counts in the file
])
def test_scan_time_error_names_the_real_line(tmp_path, comment, blank_after, line):
    p = tmp_path / "dup.csv"
    p.write_text(_scan_text(comment, blank_after))
    assert p.read_text().splitlines()[line - 1].startswith("0.019,")  # the repeated time
    with pytest.raises(RecordingError, match=rf"dup\.csv: line {line}: column 't_s' does "
                       "not increase"):
        read_scan(p)
    rows = [f"{k * 0.001:.4f},0,0,1,20" for k in range(50)]
    rows[30] = "0.0304,0,0,1,20"  # uneven step into row 30
    p.write_text("# surface=test\nt_s,ax,ay,az,speed_mm_s\n" + "\n".join(rows) + "\n")
    with pytest.raises(RecordingError, match=r"line 33: column 't_s' is unevenly sampled"):
        read_scan(p)


# ---------------------------------------------------------------- 9: fit warnings
def test_fit_warnings_are_one_line_naming_the_scans(files, tmp_path, capsys):
    scan = str(files / "R1_10.csv")
    assert run("fit", scan, str(files / "R1_30.csv"), "--out", str(tmp_path / "m.json"),
               "--speeds", "10,30,50", "--order", "10", "--form", "calibrated") == 0
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if "warning" in ln.lower()]
    assert lines == [f"fydpad texture fit: warning: {scan}, {files / 'R1_30.csv'}: no scan "
                     "has 0.25 s within 5 mm/s of 50 mm/s: no model at that speed"]
    assert "UserWarning" not in err


# ---------------------------------------------------------------- tick(nan/inf)
def test_tick_treats_a_non_finite_speed_as_no_speed():
    for structure in ("fir", "direct"):
        r = TextureRenderer(_model(), structure=structure, ramp_s=1e-3, seed=1)
        moving = np.array([r.tick(20.0) for _ in range(300)])
        assert np.std(moving) > 0
        for bad in (math.nan, math.inf, -math.inf):
            y = [r.tick(bad) for _ in range(100)]
            assert all(math.isfinite(v) for v in y)
            assert abs(y[-1]) < 1e-6 * np.std(moving)  # ramped to silence, no click
            assert abs(y[0]) < 2 * np.max(np.abs(moving))
            r.tick(20.0)
