"""The texture-family contract: registry, the LPC adapter, model-file errors, and the
station's render chain driving a family's vibration and tension channels from its one
speed input."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import scipy.signal as ss

from fydpad.errors import UserError
from fydpad.station.texture_source import open_texture, tick_speed
from fydpad.synth.texture_scans import generate_scan
from fydpad.texture.families import KINDS, fit_family, load_family
from fydpad.texture.family import TickPosition, constant_stroke, save_model_json
from fydpad.texture.lpc.family import LpcFamily
from fydpad.texture.lpc.fit import fit_paper, fit_texture
from fydpad.texture.lpc.interpolation import build_table
from fydpad.texture.lpc.model_file import save_model
from fydpad.texture.lpc.synthesis import TextureRenderer
from tests.conftest import REPO


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("families")
    scans = [generate_scan("canvas", v, 3.0, seed=1, friction=True) for v in (10.0, 30.0)]
    model = fit_texture(scans, order=40, speeds_mm_s=[10.0, 30.0])
    save_model(model, d / "lpc.json")  # an LPC file: no "kind"
    save_model_json(fit_family("friction", scans[:1]), d / "friction.json")
    save_model_json(fit_family("grating", None, wavelength_mm=2.15), d / "grating.json")
    return d


def test_registry_and_kind_from_file(files):
    for k in ("lpc", "friction", "grating"):
        assert k in KINDS or load_family(str(files / f"{k}.json")).kind == k
    fam = load_family(str(files / "lpc.json"))
    assert isinstance(fam, LpcFamily) and fam.tick_channels == ("vibration",)
    assert load_family(f"friction:{files / 'friction.json'}").kind == "friction"
    g = load_family(f"grating:{files / 'grating.json'}")
    assert g.tick_channels == ("vibration", "tension") and "audio" in g.channels


def test_lpc_adapter_renders_what_the_renderer_does(files):
    fam = load_family(str(files / "lpc.json"))
    fam.set_parameter("seed", 3)
    fb = constant_stroke(20.0, 1.0, 1000.0)
    y = fam.render(fb, "vibration")
    r = TextureRenderer(fam.model, seed=3, ramp_s=1e-6)
    r.warmup(20.0, 0.5)
    np.testing.assert_array_equal(y, r.block(fb.speed_mm_s, fb.contact))
    fam.prepare(1000.0)
    vals = [fam.tick(k / 1000, True, 10 + 0.02 * k, 5.0, 20.0, 1.0)[0] for k in range(600)]
    assert np.std(vals[300:]) > 0


@pytest.mark.parametrize(("kind", "edit", "says"), [
    ("friction", {"kind": "velvet"}, "key 'kind' is 'velvet', not a texture family"),
    ("friction", {"kind": "grating"}, "missing key 'wavelength_mm'"),
    ("friction", {"format_version": 2}, "key 'format_version'"),
    ("friction", {"mu": None}, "key 'mu'"),
    ("friction", {"mu": [0.5, -1.0]}, "key 'mu'"),
    ("friction", {"dx_mm": 0}, "key 'dx_mm'"),
    ("grating", {"ratio": [6, 6]}, "key 'ratio'"),
    ("grating", {"wavelength_mm": None}, "key 'wavelength_mm'"),
    ("grating", {"profile": "triangle"}, "key 'profile'"),
    ("grating", {"format_version": 0}, "key 'format_version'"),
    ("grating", {"levels": {"vibrotactile_n": [0.1]}}, "key 'vibrotactile_n'"),
    # The optional sections: each a JSON object of finite numbers.
    ("friction", {"electrostatic": []}, "key 'electrostatic' must be an object"),
    ("friction", {"electrostatic": {"b_v": "x"}}, "electrostatic: key 'b_v' has the wrong"),
    ("friction", {"electrostatic": {"carrier_hz": 0}}, "key 'carrier_hz' must be positive"),
    ("friction", {"fydpad": {"still_mm_s": True}}, "fydpad: key 'still_mm_s' has the wrong"),
    ("grating", {"electrostatic": {"mu": 0}}, "electrostatic: key 'mu' must be positive"),
    ("grating", {"electrostatic": {"mu": "x"}}, "electrostatic: key 'mu' has the wrong"),
    ("grating", {"fydpad": 3}, "key 'fydpad' must be an object"),
    ("grating", {"ridge_fraction": "a"}, "key 'ridge_fraction' has the wrong type"),
    ("grating", {"ridge_fraction": 1.5}, "key 'ridge_fraction' must be in (0, 1)"),
    # Values the render divides by.
    ("friction", {"fydpad": {"still_mm_s": 0}}, "key 'still_mm_s' must be positive"),
    ("grating", {"electrostatic": {"load_n": 0}}, "key 'load_n' must be positive"),
    ("grating", {"levels": {"vibrotactile_n": [0.1, 0], "friction_n": [0.02, 0.2]}},
     "key 'vibrotactile_n' must be [level_1, level_10], non-negative, level 10 positive"),
])
def test_bad_model_file_names_file_and_key(files, tmp_path, kind, edit, says):
    data = json.loads((files / f"{kind}.json").read_text())
    for k, v in edit.items():
        if v is None:
            del data[k]
        else:
            data[k] = v
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(data))
    with pytest.raises(UserError) as e:
        load_family(str(bad))
    assert str(bad) in str(e.value) and says in str(e.value)


def test_spec_kind_must_match(files):
    with pytest.raises(UserError, match="key 'kind' is 'grating', but the spec asked for"):
        load_family(f"friction:{files / 'grating.json'}")
    with pytest.raises(UserError, match="unknown texture kind"):
        fit_family("nope", [])


def _station_ticks(family, x_of_t, n: int = 3000) -> np.ndarray:
    """The family ticked as the station does: the newest camera centroid (30 frames/s,
    held between frames) and the station's one speed estimate from it."""
    speed = tick_speed()
    out = np.empty(n)
    for k in range(n):
        t = k / 1000.0
        x = x_of_t(np.floor(t * 30.0) / 30.0)
        speed.sample(t, x, 10.0, True)
        out[k] = family.tick(t, True, x, 10.0, speed.tick(1e-3), 1.0)[0]
    return out


def _ticks(family, n: int = 3000) -> np.ndarray:
    # A finger crossing at 20 mm/s.
    return _station_ticks(family, lambda t: 5.0 + 20.0 * t, n)[1000:]


def test_station_renders_the_files_interpolation_and_the_drive_band(files, tmp_path):
    """The station's 1 kHz path renders the interpolation the model file names (the one
    the commands score: "stretch" for the calibrated form, "nearest" for the paper's
    per-speed fits), and --drive-filter puts the vibration in the model's drive band
    (165-220 Hz, Bianchi 2015 III-B)."""
    model_path = str(files / "lpc.json")
    plain = open_texture(model_path, 1000.0)
    assert plain.model.interpolation == plain.tick_renderer.interpolation == "stretch"
    table = build_table(plain.model)
    np.testing.assert_array_equal(plain.tick_renderer.table.polys, table.polys)
    scans = [generate_scan("canvas", v, 3.0, seed=1) for v in (10.0, 30.0)]
    save_model(fit_paper(scans, order=40), tmp_path / "paper.json")
    per_speed = open_texture(str(tmp_path / "paper.json"), 1000.0)
    assert per_speed.tick_renderer.interpolation == "nearest"
    m, lin = per_speed.model, per_speed.tick_renderer.table
    for v in (m.speeds_mm_s[0], 20.0, 20.4, m.speeds_mm_s[-1]):  # the nearest fit, unchanged
        j = int(np.argmin(np.abs(m.speeds_mm_s - v)))
        np.testing.assert_array_equal(lin.polys[lin.index(v)], m.poly(j))
    band = open_texture(model_path, 1000.0, drive_filter=True)
    # One noise draw through both: what differs is the filter alone.
    for family in (plain, band):
        family.set_parameter("seed", 7)
        family.prepare(1000.0)
    lo, hi = plain.model.drive_band_hz
    # Power through the drive filter against without it, per band (dB), on the same draw:
    # the filter's own work (measured -30 and -32 dB out of band, -0.8 in it).
    f, p_plain = ss.welch(_ticks(plain), fs=1000.0, nperseg=256)
    _, p_band = ss.welch(_ticks(band), fs=1000.0, nperseg=256)

    def gain_db(a: float, b: float) -> float:
        m = (f >= a) & (f <= b)
        return float(10 * np.log10(p_band[m].sum() / p_plain[m].sum()))

    gains = {"below": gain_db(20, 120), "in": gain_db(lo, hi), "above": gain_db(300, 500)}
    assert abs(gains["in"]) < 2.0 and gains["below"] < -25 and gains["above"] < -25, gains


def test_station_texture_falls_silent_when_the_finger_stops(files):
    """A finger crossing at 20 mm/s for 1 s, then held still (the camera's centroid
    exactly unchanged, as a replay or a quantised tracker gives it): through the
    station's speed estimate the vibration is there while it moves and gone within 0.5 s
    of the stop."""
    src = open_texture(str(files / "lpc.json"), 1000.0)
    out = _station_ticks(src, lambda t: 5.0 + 20.0 * min(t, 1.0))
    moving = np.sqrt(np.mean(out[400:1000] ** 2))
    still = np.sqrt(np.mean(out[1500:] ** 2))
    assert moving > 0 and still < 1e-3 * moving, (moving, still)


def test_lpc_options_on_another_family_are_one_line_errors(files, capsys):
    from fydpad.cli import main

    with pytest.raises(UserError, match="--drive-filter applies to LPC"):
        open_texture(str(files / "friction.json"), 1000.0, drive_filter=True)
    assert main(["run", "--synthetic", "circle", "--motors", "sim", "--texture",
                 str(files / "grating.json"), "--drive-filter"]) == 2
    err = capsys.readouterr().err
    assert "grating.json: --drive-filter applies to LPC" in err
    assert err.count("\n") == 1
    assert main(["run", "--synthetic", "circle", "--drive-filter"]) == 2
    assert "needs --texture MODEL" in capsys.readouterr().err


def test_command_line_bad_model_is_one_line_exit_2(files, tmp_path):
    bad = tmp_path / "m.json"
    bad.write_text(json.dumps({"format": "fydpad-texture-model", "kind": "friction",
                               "format_version": 1, "dx_mm": 0.01, "x0_mm": 0}))
    r = subprocess.run([sys.executable, "-m", "fydpad.cli", "texture", "synth", str(bad),
                        "--speed-mm-s", "10", "--seconds", "1", "--out",
                        str(tmp_path / "o.csv")], capture_output=True, text=True, cwd=REPO,
                       timeout=60)
    assert r.returncode == 2 and r.stderr.count("\n") == 1
    assert "m.json: missing key 'mu'" in r.stderr


def test_switching_stimuli_starts_the_next_from_no_speed(files):
    """Switching stimuli resets the station's speed estimate too: 1 s at 40 mm/s, then a
    switch and a finger at 10 mm/s: the estimate rises towards 10, never from 40."""
    from fydpad.config import StationConfig
    from fydpad.station.chains import build_render_chain
    from fydpad.station.render import RenderSpec

    lpc = str(files / "lpc.json")
    chain = build_render_chain(RenderSpec(texture=lpc, textures=(lpc,), motors="sim",
                                          config=StationConfig()))
    try:
        for k in range(1000):
            t = k / 1000.0
            chain.tick(t, True, 40.0 * np.floor(t * 30) / 30, 0.0, 40.0, 1.0, 1.0, 0.6)
        assert chain.speed.tick(0.0) > 35.0
        chain.apply_control(1, float("nan"))
        for k in range(1000, 1060):
            t = k / 1000.0
            chain.tick(t, True, 10.0 * np.floor(t * 30) / 30, 0.0, 10.0, 1.0, 1.0, 0.6)
            assert chain.speed.tick(0.0) < 10.5
    finally:
        chain.safe_stop()


def test_lpc_options_reach_lpc_stimuli_and_pass_over_the_others(files):
    """An experiment's stimuli mix families: --drive-filter applies to its LPC models
    and passes over a grating (it stopped the station at start)."""
    from fydpad.config import StationConfig
    from fydpad.station.chains import build_render_chain
    from fydpad.station.render import RenderSpec

    spec = RenderSpec(texture=str(files / "lpc.json"),
                      textures=(f"grating:{files / 'grating.json'}", str(files / "lpc.json")),
                      motors="sim", config=StationConfig(), drive_filter=True)
    chain = build_render_chain(spec)
    try:
        lpc0, grating, lpc2 = (m.family for m in chain.models)
        for fam in (lpc0, lpc2):
            assert fam.tick_renderer._sos is not None
        assert grating.kind == "grating"
    finally:
        chain.safe_stop()


def test_drive_chain_plays_vibration_and_scales_stiffness_by_tension(files):
    """The station's render chain on the simulated motors: the grating's tension channel
    moves the softness request around the specimen's stiffness, by position."""
    from fydpad.config import StationConfig
    from fydpad.station.chains import build_render_chain
    from fydpad.station.render import RenderSpec

    spec = RenderSpec(texture=f"grating:{files / 'grating.json'}", motors="sim",
                      config=StationConfig())
    chain = build_render_chain(spec)
    try:
        k0 = 0.6
        lo, hi = chain._k_lo, chain._k_hi
        assert lo < k0 < hi
        req, vib = [], []
        for i in range(1500):  # 1.5 s at 20 mm/s, centroids at 30 fps
            t = i / 1000
            x = 20.0 * np.floor(t * 30) / 30
            v, *_ = chain.tick(t, True, x, 5.0, 20.0, 1.0, 1.0, k0)
            vib.append(v)
            req.append(chain.drive.requested_k_n_per_mm)
        req, vib = np.asarray(req[200:]), np.asarray(vib[200:])
        assert req.min() < k0 < req.max()
        assert _peak(vib) == pytest.approx(20.0 / 2.15, abs=1.0)
        assert _peak(req) == pytest.approx(20.0 / 2.15, abs=1.0)
    finally:
        chain.safe_stop()


def _peak(y):
    f = np.fft.rfftfreq(8 * y.size, 1e-3)
    p = np.abs(np.fft.rfft((y - y.mean()) * np.hanning(y.size), 8 * y.size))
    return f[np.argmax(p)]


def test_tick_position_extrapolates_between_frames_and_rests_when_the_finger_stops():
    """30 fps centroids of a finger at 100 mm/s that stops at 10 mm: between frames the
    position runs on along the velocity; once the centroid stays put, the position is the
    centroid itself (not 10 mm + v * hold)."""
    pos = TickPosition()
    frame_s = 1 / 30
    out = []
    for k in range(3000):  # 3 s of 1 kHz ticks
        t = k / 1000
        frame_t = np.floor(t / frame_s) * frame_s
        x = min(100.0 * frame_t, 10.0)  # the newest centroid, held between frames
        out.append(pos.update(t, True, x))
    out = np.array(out)
    t = np.arange(3000) / 1000
    moving = (t > 0.07) & (t < 0.099)  # from the third frame on: a velocity
    assert np.max(np.abs(out[moving] - 100.0 * t[moving])) < 1.0  # runs on, not steps
    assert np.all(out[t > 0.5] == 10.0)  # at rest: exactly where the finger stopped


def test_the_render_process_warns_on_one_line(tmp_path):
    """A warning from the render process (a speed above the fastest model's range) is one
    line naming the command, not Python's file:line and code line."""
    scans = [generate_scan("canvas", 10.0, 3.0, seed=1, friction=True)]
    model = fit_paper(scans, order=40)
    save_model(model, tmp_path / "slow.json")  # clamped above ~13 mm/s; the circle is faster
    # The bundled circle recording: the finger is on the fabric and moving from its first
    # frames, however few frames a loaded machine tracks a second.
    r = subprocess.run([sys.executable, "-m", "fydpad.cli", "run", "--replay",
                        str(REPO / "recordings" / "circle"), "--as-fast-as-possible",
                        "--motors", "sim", "--texture", str(tmp_path / "slow.json")],
                       capture_output=True, text=True, cwd=REPO, timeout=300)
    assert r.returncode == 0, r.stderr
    warned = [ln for ln in r.stderr.splitlines() if "clamped" in ln]
    assert len(warned) == 1 and warned[0].startswith("fydpad run: warning: canvas: speed "), \
        r.stderr
    assert "Warning:" not in r.stderr and "texture_source.py" not in r.stderr, r.stderr
