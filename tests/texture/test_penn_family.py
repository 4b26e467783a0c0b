"""The HaTT texture family (kind "penn"): load, tick, render, the CLI; on small files in
the toolkit's schema written here (the toolkit's own files are not shipped)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import scipy.signal as ss

from fydpad.errors import UserError
from fydpad.synth.hatt import write_penn
from fydpad.texture.families import load_family, spec_kind
from fydpad.texture.families.penn.render import PennTexture
from fydpad.texture.families.penn.toolkit import PennModelSet
from fydpad.texture.family import constant_stroke
from tests.texture.lpc_polys import poly_to_lsf, reflection_to_poly

FS = 10_000.0


def _resonator(f_hz: float, r: float = 0.97) -> np.ndarray:
    w = 2 * np.pi * f_hz / FS
    return np.convolve([1, -2 * r * np.cos(w), r * r], reflection_to_poly([0.3, -0.2]))


def _model_set(res_hz, name="tex") -> PennModelSet:
    """Four ARMA(4, 2) models on a 2 x 2 speed x force grid (two Delaunay triangles)."""
    speeds = np.array([20.0, 200.0, 20.0, 200.0])
    forces = np.array([0.5, 0.5, 3.0, 3.0])
    ar = np.vstack([poly_to_lsf(_resonator(f)) for f in res_hz])
    ma = np.vstack([poly_to_lsf(reflection_to_poly([0.5 * s, 0.2])) for s in (0.2, 0.4, 0.6, 0.8)])
    return PennModelSet(name, FS, speeds, forces, np.array([[0, 1, 2], [1, 3, 2]]), ar, ma,
                        np.array([1e-4, 2e-4, 3e-4, 4e-4]), np.array([1.0, 1.5, 2.0, 2.5]),
                        200.0, 3.0)


@pytest.fixture(scope="module")
def penn_xml(tmp_path_factory):
    return write_penn(tmp_path_factory.mktemp("penn") / "Models_Tex.xml",
                      _model_set((120, 260, 180, 340)))


def _tick_stroke(fam, speed_mm_s, force_n, seconds, t0_s=0.0, x0_mm=10.0, contact=True):
    """Tick ``seconds`` with a centroid moving at ``speed_mm_s``, seen at 30 fps (held)."""
    n = round(seconds * 1000)
    t = t0_s + np.arange(n) / 1000.0
    force = np.broadcast_to(np.asarray(force_n, float), (n,))
    x = x0_mm + speed_mm_s * np.floor(t * 30) / 30
    return np.array([fam.tick(t[k], contact, x[k], 5.0, speed_mm_s, force[k])[0]
                     for k in range(n)])


def _theory_psd(fam, cell, f):
    """One-sided PSD at the output rate: the ARMA spectrum at the model rate times the
    decimation low-pass (what folds onto 20-450 Hz is >= 60 dB down)."""
    _, g = ss.freqz(fam.num[cell], fam.den[cell], worN=f, fs=FS)
    _, h = ss.sosfreqz(fam.sos, worN=f, fs=FS)
    return 2 * fam.sigma[cell] ** 2 / FS * np.abs(g * h) ** 2


def _db_rms(p, ref, f, band=(20.0, 450.0)):
    sel = (f >= band[0]) & (f <= band[1])
    return float(np.sqrt(np.mean((10 * np.log10(p[sel] / ref[sel])) ** 2)))


def test_loaded_by_spec_and_suffix(penn_xml):
    for spec in (str(penn_xml), f"penn:{penn_xml}"):
        fam = load_family(spec)
        assert isinstance(fam, PennTexture) and fam.kind == "penn"
        assert fam.tick_channels == ("vibration",) and fam.surface == "tex"
        assert spec_kind(spec) == "penn"
    with pytest.raises(UserError, match=r"nope\.xml: missing"):
        load_family("penn:nope.xml")


def test_tick_step_is_the_recursion_then_the_low_pass(penn_xml):
    """One matrix per grid point equals the toolkit's recursion (lfilter) followed by the
    anti-alias low-pass (sosfilt) and every 10th sample, to rounding."""
    fam = load_family(penn_xml)
    fam.prepare(1000.0)
    cell = int(fam.cells(np.array([120.0]), np.array([1.7]))[0])
    r, d = fam.ratio, fam._d
    assert r == 10
    n = np.random.default_rng(3).standard_normal(r * 400)
    state = np.zeros(d + r)
    got = []
    for k in range(400):
        state[d:] = n[k * r:(k + 1) * r]
        out = fam._W[cell] @ state
        state[:d] = out[:d]
        got.append(out[d])
    y = ss.lfilter(fam.num[cell], fam.den[cell], fam.sigma[cell] * n)
    want = ss.sosfilt(fam.sos, y)[r - 1::r]
    np.testing.assert_allclose(got, want, atol=1e-12 * np.abs(want).max())


def test_tick_and_render_agree_in_spectrum(penn_xml):
    """At a grid speed and force: Welch PSDs (30 s, 256-sample segments) of tick and
    render within 1 dB RMS of each other and of the ARMA x low-pass spectrum, 20-450 Hz."""
    fam = load_family(penn_xml)
    fam.prepare(1000.0)
    v, force = float(fam.speed_grid_mm_s[32]), float(fam.force_grid_n[12])
    cell = int(fam.cells(np.array([v]), np.array([force]))[0])
    ticked = _tick_stroke(fam, v, force, 31.0)[1000:]
    rendered = load_family(penn_xml).render(constant_stroke(v, 31.0, 1000.0, force_n=force))
    rendered = rendered[1000:]
    f, pt = ss.welch(ticked, 1000.0, nperseg=256)
    _, pr = ss.welch(rendered, 1000.0, nperseg=256)
    ref = _theory_psd(fam, cell, f)
    assert _db_rms(pt, pr, f) < 1.0
    assert _db_rms(pt, ref, f) < 1.0
    assert _db_rms(pr, ref, f) < 1.0


def test_tick_decimation_is_anti_aliased(tmp_path):
    """Models ringing at 1.4 kHz (above the 500 Hz Nyquist of the output): the ticked
    signal at 350-450 Hz stays the model's own level there, where keeping every 10th
    model sample without the low-pass would fold the resonance onto 400 Hz."""
    path = write_penn(tmp_path / "hi.xml", _model_set((1400, 1400, 1400, 1400), "hi"))
    fam = load_family(path)
    fam.prepare(1000.0)
    cell = int(fam.cells(np.array([fam.speed_grid_mm_s[20]]), np.array([1.0]))[0])
    y = _tick_stroke(fam, float(fam.speed_grid_mm_s[20]), 1.0, 21.0)[1000:]
    f, p = ss.welch(y, 1000.0, nperseg=256)
    band = (350.0, 450.0)
    assert _db_rms(p, _theory_psd(fam, cell, f), f, band) < 1.5
    # The same process decimated without the low-pass: the alias the filter removes.
    x = ss.lfilter(fam.num[cell], fam.den[cell],
                   fam.sigma[cell] * np.random.default_rng(0).standard_normal(200_000))
    _, pn = ss.welch(x[::10], 1000.0, nperseg=256)
    sel = (f >= band[0]) & (f <= band[1])
    assert 10 * np.log10(pn[sel].mean() / p[sel].mean()) > 15.0  # measured 19.7 dB


def test_force_step_carries_the_state_without_a_click(penn_xml):
    """A step in force (the load cell) switches the model at once; the filter state goes
    on, so no sample near the step stands out of either side's level (a reset or a
    mis-mapped state would silence or burst), and the level changes to the new model's."""
    fam = load_family(penn_xml)
    fam.prepare(1000.0)
    v = float(fam.speed_grid_mm_s[40])
    force = np.where(np.arange(6000) < 3000, 0.6, 2.8)
    y = _tick_stroke(fam, v, force, 6.0)
    before, after = y[2000:2990].std(), y[3300:5990].std()
    near = np.abs(y[2990:3030])
    assert near.max() < 4.5 * max(before, after)
    assert np.sqrt(np.mean(near[10:20] ** 2)) > 0.3 * min(before, after)  # no silence
    cells = fam.cells(np.array([v, v]), np.array([0.6, 2.8]))
    want = [np.sqrt(np.trapezoid(_theory_psd(fam, c, np.linspace(0, 500, 2001)),
                                 np.linspace(0, 500, 2001))) for c in cells]
    assert before == pytest.approx(want[0], rel=0.15)
    assert after == pytest.approx(want[1], rel=0.15)


def test_render_blocks_continue_across_calls(penn_xml):
    """Two render calls with different forces: one continuous signal (state carried)."""
    fam = load_family(penn_xml)
    a = fam.render(constant_stroke(100.0, 2.0, 1000.0, force_n=0.6))
    b = fam.render(constant_stroke(100.0, 2.0, 1000.0, force_n=2.8))
    lvl = max(a[1000:].std(), b[500:].std())
    assert np.abs(np.concatenate([a[-20:], b[:20]])).max() < 4.5 * lvl
    assert np.sqrt(np.mean(b[:10] ** 2)) > 0.3 * a[1000:].std()


def test_silent_without_contact_or_when_still(penn_xml):
    fam = load_family(penn_xml)
    fam.prepare(1000.0)
    assert np.abs(_tick_stroke(fam, 100.0, 1.0, 1.0)[500:]).max() > 0
    off = _tick_stroke(fam, 100.0, 1.0, 0.5, t0_s=1.0, contact=False)
    assert np.abs(off[100:]).max() < 1e-6 * np.abs(off[:5]).max() + 1e-12
    fam.reset()
    _tick_stroke(fam, 100.0, 1.0, 1.0)
    still = _tick_stroke(fam, 0.0, 1.0, 1.0, t0_s=1.0, x0_mm=10.0 + 100.0 * 29 / 30)
    assert np.abs(still[600:]).max() < 1e-3 * np.abs(still[:20]).max()
    # offline: the same gate
    fb = constant_stroke(100.0, 1.0, 1000.0)
    y = fam.render(type(fb)(fb.fs_hz, fb.t_s, np.arange(1000) < 500, fb.x_mm, fb.y_mm,
                            fb.speed_mm_s, fb.force_n))
    assert np.abs(y[600:]).max() < 1e-6 * np.abs(y[400:500]).max()


def test_other_rates(penn_xml):
    """render at an audio rate (resample_poly) has the same level in band; a tick rate
    the model rate is not a whole multiple of is refused, naming the file."""
    fam = load_family(penn_xml)
    y1 = fam.render(constant_stroke(100.0, 10.0, 1000.0, force_n=1.0))[1000:]
    fam.reset()
    y48 = fam.render(constant_stroke(100.0, 10.0, 48_000.0, force_n=1.0))[48_000:]
    assert y48.size == 9 * 48_000
    f, p1 = ss.welch(y1, 1000.0, nperseg=256)
    _, p48 = ss.welch(y48, 48_000.0, nperseg=256 * 48)
    assert _db_rms(p1, p48[:f.size], f, (20.0, 400.0)) < 1.5
    with pytest.raises(UserError, match=r"Models_Tex\.xml: <SampleRate> 10000 Hz is not"):
        fam.prepare(3000.0)


def _cli(*argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "fydpad.cli", "texture", *argv],
                          capture_output=True, text=True, timeout=120)


def test_cli_synth(tmp_path, penn_xml):
    out = tmp_path / "wood.csv"
    r = _cli("synth", str(penn_xml), "--speed-mm-s", "100", "--force-n", "1.5",
             "--seconds", "2", "--out", str(out))
    assert r.returncode == 0, r.stderr
    lines = [ln for ln in out.read_text().splitlines() if not ln.startswith("#")]
    assert lines[0] == "t_s,a" and len(lines) == 2001
    t, a = np.loadtxt(lines[1:], delimiter=",").T
    np.testing.assert_allclose(np.diff(t), 1e-3, atol=1e-9)
    fam = load_family(penn_xml)
    cell = int(fam.cells(np.array([100.0]), np.array([1.5]))[0])
    fam.prepare(1000.0)
    f = np.linspace(0, 500, 2001)
    want = np.sqrt(np.trapezoid(_theory_psd(fam, cell, f), f))
    assert a.std() == pytest.approx(want, rel=0.2)  # steady from the first sample
    assert a[:50].std() == pytest.approx(want, rel=0.5)
    r = _cli("synth", f"penn:{penn_xml}", "--speed-mm-s", "100", "--seconds", "1",
             "--out", str(out))
    assert r.returncode != 0
    assert f"{penn_xml}: a HaTT model is indexed by speed and force: give --force-n" in r.stderr
    bad = tmp_path / "bad.xml"
    bad.write_text(penn_xml.read_text().replace("<numMACoeff>2", "<numMACoeff>3"))
    r = _cli("synth", str(bad), "--speed-mm-s", "100", "--force-n", "1", "--seconds", "1",
             "--out", str(out))
    assert r.returncode != 0 and "bad.xml: model 1: <MAlsf> has 2 values" in r.stderr


def test_station_render_chain_plays_a_hatt_file(penn_xml):
    """``fydpad run --texture penn:FILE.xml``'s render chain on the simulated motors: the
    texture opened as the station does (open_texture: rate set, prepared), vibration out
    with the level of the model at the stroke's speed and the load cell's force."""
    from fydpad.config import StationConfig
    from fydpad.station.chains import build_render_chain
    from fydpad.station.render import RenderSpec

    chain = build_render_chain(RenderSpec(texture=f"penn:{penn_xml}", motors="sim",
                                          config=StationConfig()))
    try:
        fam = chain.texture.family
        assert fam.kind == "penn" and fam._tick_ready
        vib = []
        for i in range(3000):  # 3 s at 100 mm/s, centroids at 30 fps, 1.5 N
            t = i / 1000
            v, *_ = chain.tick(t, True, 10.0 + 100.0 * np.floor(t * 30) / 30, 5.0, 100.0,
                               1.5, 1.0, 0.6)
            vib.append(v)
        cell = int(fam.cells(np.array([chain.speed.tick(0.0)]), np.array([1.5]))[0])
        f = np.linspace(0, 500, 2001)
        want = np.sqrt(np.trapezoid(_theory_psd(fam, cell, f), f))
        assert np.std(vib[1000:]) == pytest.approx(want, rel=0.2)
    finally:
        chain.safe_stop()


def test_a_set_at_the_tick_rate_needs_no_low_pass(tmp_path):
    """The toolkit's resampled sets (e.g. SampleRate 1000): one model sample a tick,
    no decimation filter, the ARMA spectrum itself."""
    ms = _model_set((120, 260, 180, 340))
    ms.fs_hz = 1000.0
    fam = load_family(write_penn(tmp_path / "Models_1k.xml", ms))
    fam.prepare(1000.0)
    assert fam.ratio == 1 and fam.sos.shape == (0, 6)
    v, force = float(fam.speed_grid_mm_s[30]), 1.0
    y = _tick_stroke(fam, v, force, 21.0)[1000:]
    cell = int(fam.cells(np.array([v]), np.array([force]))[0])
    f, p = ss.welch(y, 1000.0, nperseg=256)
    _, g = ss.freqz(fam.num[cell], fam.den[cell], worN=f, fs=1000.0)
    assert _db_rms(p, 2 * fam.sigma[cell] ** 2 / 1000.0 * np.abs(g) ** 2, f) < 1.0
    r = fam.render(constant_stroke(v, 21.0, 1000.0, force_n=force))[1000:]
    _, pr = ss.welch(r, 1000.0, nperseg=256)
    assert _db_rms(p, pr, f) < 1.0


def test_cli_evaluate_and_identify_take_hatt_files(tmp_path, penn_xml, capsys):
    """A HaTT set scored against a scan (its speed and force trace) and two sets in a
    confusion matrix, through the commands' own entry (fydpad.cli.main)."""
    import json

    from fydpad.cli import main
    from fydpad.synth.texture_scans import generate_scan, save_generated

    scan = save_generated(generate_scan("felt", 30.0, 3.0, seed=2), tmp_path / "felt.csv")
    other = write_penn(tmp_path / "Models_Other.xml", _model_set((60, 70, 65, 75), "other"))
    assert main(["texture", "evaluate", str(penn_xml), str(scan), "--json",
                 str(tmp_path / "e.json")]) == 0
    e = json.loads((tmp_path / "e.json").read_text())
    assert e["kind"] == "penn" and np.isfinite(e["lsd_db"])
    assert "penn: power-spectrum correlation" in capsys.readouterr().out
    assert main(["texture", "identify", str(penn_xml), f"penn:{other}", "--scans", str(scan),
                 "--json", str(tmp_path / "i.json")]) == 0
    ident = json.loads((tmp_path / "i.json").read_text())
    assert ident["kind"] == "penn" and {"tex", "other"} <= set(ident["labels"])


def _tick_transient_b(step, n: int = 2000) -> float:
    """Median over ``n`` calls of tracemalloc's peak minus current across one call."""
    import gc
    import tracemalloc

    for k in range(500):
        step(k)
    gc.collect()
    gc.disable()
    tracemalloc.start()
    peaks = np.zeros(n)
    try:
        for k in range(500, 500 + n):
            c, _ = tracemalloc.get_traced_memory()
            tracemalloc.reset_peak()
            step(k)
            peaks[k - 500] = tracemalloc.get_traced_memory()[1] - c
    finally:
        tracemalloc.stop()
        gc.enable()
    return float(np.median(peaks))


def test_tick_creates_no_arrays(penn_xml):
    """tick's own step (grid point, noise, matrix, gate) allocates nothing: the noise
    block and the matrices are indexed through views made in prepare (the speed is
    the station's input)."""
    fam = load_family(penn_xml)
    fam.prepare(1000.0)
    ts = (np.arange(3000) / 1000.0).tolist()
    fs = (1.0 + 0.5 * np.sin(np.arange(3000) / 300)).tolist()  # grid points change
    got = _tick_transient_b(lambda k: fam.tick(ts[k], True, 10.0, 5.0, 20.0, fs[k]))
    assert got == 0.0  # the old tick's slice views: 224 B
    assert fam._npos > 0  # the noise block was redrawn in the loop (512 ticks each)


def test_table_budget_uses_the_real_low_pass(tmp_path):
    """ARMA(25, 5) at 10 kHz: the tick matrices of the full 64 x 32 grid (4 low-pass
    sections, 30.7 MB) fit the 32 MiB budget; AR(60) shrinks the grid to fit it."""
    from fydpad.texture.families.penn.render import _TABLE_BYTES, decimation_sos

    assert decimation_sos(10, 1000.0).shape[0] == 4
    rng = np.random.default_rng(0)
    ms = _model_set((120, 260, 180, 340))
    for p, q, grid in ((25, 5, (64, 32)), (60, 0, None)):
        ms.ar_lsf = np.sort(rng.uniform(0.05, 3.0, (4, p)), axis=1)
        ms.ma_lsf = np.sort(rng.uniform(0.05, 3.0, (4, q)), axis=1)
        fam = PennTexture(ms, "m.xml")
        if grid is not None:
            assert fam._grid == grid
        else:
            assert fam._grid[0] * fam._grid[1] < 64 * 32
        fam.prepare(1000.0)
        assert fam._W.nbytes <= _TABLE_BYTES
        assert fam._W.shape[0] == fam._grid[0] * fam._grid[1]


def test_cli_synth_refuses_a_non_finite_speed(tmp_path, penn_xml, capsys):
    """--speed-mm-s inf or -1: one line naming the flag, for every kind (penn wrote
    silence with a RuntimeWarning)."""
    from fydpad.cli import main

    for speed in ("inf", "nan", "-1"):
        rc = main(["texture", "synth", f"penn:{penn_xml}", "--speed-mm-s", speed,
                   "--force-n", "1", "--seconds", "1", "--out", str(tmp_path / "o.csv")])
        err = capsys.readouterr().err
        assert rc == 2 and "--speed-mm-s" in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "o.csv").exists()


def test_run_checks_the_model_rate_before_the_station_starts(tmp_path, monkeypatch, capsys):
    """A set at 10.5 kHz cannot tick at 1 kHz: ``fydpad run`` says so in one line from
    the family's check_rate, before a Station (and its render process) exists."""
    import fydpad.station.station as station_module
    from fydpad.cli import main

    ms = _model_set((120, 260, 180, 340))
    ms.fs_hz = 10_500.0
    xml = write_penn(tmp_path / "Models_Odd.xml", ms)
    with pytest.raises(UserError, match=r"Models_Odd\.xml: <SampleRate> 10500 Hz is not a whole"):
        load_family(xml).check_rate(1000.0)
    load_family(xml).check_rate(500.0)  # 21 x 500 Hz: fine

    def no_station(*a, **k):
        raise AssertionError("the station was started")

    # `fydpad run` imports the Station from its module when it runs.
    monkeypatch.setattr(station_module, "Station", no_station)
    rc = main(["run", "--synthetic", "--duration", "1", "--motors", "sim",
               "--texture", f"penn:{xml}"])
    err = capsys.readouterr().err
    assert rc == 2 and "<SampleRate> 10500 Hz is not a whole multiple" in err, err
    assert len(err.strip().splitlines()) == 1
