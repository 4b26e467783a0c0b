"""Penn Haptic Texture Toolkit import, on a small file in its schema written here."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as ss

from fydpad.errors import UserError
from fydpad.synth.hatt import PennRenderer, interpolate, write_penn
from fydpad.texture.families.penn.toolkit import PennModelSet, read_penn
from fydpad.texture.lpc.lsf import lsf_to_poly
from tests.texture.lpc_polys import poly_to_lsf, reflection_to_poly


def _resonator(f_hz: float, fs: float, r: float = 0.97) -> np.ndarray:
    w = 2 * np.pi * f_hz / fs
    return np.convolve([1, -2 * r * np.cos(w), r * r], reflection_to_poly([0.3, -0.2]))


@pytest.fixture
def penn_file(tmp_path):
    fs = 10_000.0
    # A speed x force grid of 4 models: two triangles.
    speeds = np.array([50.0, 200.0, 50.0, 200.0])
    forces = np.array([0.5, 0.5, 2.0, 2.0])
    ar = np.vstack([poly_to_lsf(_resonator(f, fs)) for f in (300, 600, 400, 800)])
    ma = np.vstack([poly_to_lsf(reflection_to_poly([0.5 * s, 0.2])) for s in (0.2, 0.4, 0.6, 0.8)])
    ms = PennModelSet("test_tex", fs, speeds, forces, np.array([[0, 1, 2], [1, 3, 2]]), ar, ma,
                      np.array([1e-4, 2e-4, 3e-4, 4e-4]), np.array([1.0, 1.5, 2.0, 2.5]),
                      400.0, 4.0)
    return write_penn(tmp_path / "test_tex.xml", ms), ms


def test_read_back_the_schema(penn_file):
    path, ms = penn_file
    text = path.read_text()
    for tag in ("<modelSet>", "<numMod>4", "<numARCoeff>4", "<numMACoeff>2", "<ARlsf>",
                "<MAlsf>", "<speedMod>", "<forceMod>", "<var>", "<gain>", "<tri>"):
        assert tag in text
    back = read_penn(path)
    np.testing.assert_allclose(back.ar_lsf, ms.ar_lsf)
    np.testing.assert_array_equal(back.tri, ms.tri)  # 1-based in the file, 0-based here


def test_interpolation_at_vertices_and_inside(penn_file):
    path, ms = penn_file
    m = read_penn(path)
    a, _b, var, gain = interpolate(m, 200.0, 0.5)
    np.testing.assert_allclose(a, lsf_to_poly(ms.ar_lsf[1]), atol=1e-10)
    assert (var, gain) == pytest.approx((2e-4, 1.5))
    # Centroid of triangle (0, 1, 2): equal weights of the three LSF sets.
    a, _, var, _ = interpolate(m, 100.0, 1.0)
    np.testing.assert_allclose(a, lsf_to_poly(ms.ar_lsf[[0, 1, 2]].mean(axis=0)), atol=1e-10)
    assert var == pytest.approx(2e-4)


def test_rendered_spectrum_is_the_arma_spectrum(penn_file):
    path, _ms = penn_file
    m = read_penn(path)
    r = PennRenderer(m, seed=1)
    r.block(50.0, 0.5, 2000)
    y = np.concatenate([r.block(50.0, 0.5, 1000) for _ in range(200)])  # 20 s in blocks
    a, b, var, gain = interpolate(m, 50.0, 0.5)
    f, p = ss.welch(y, m.fs_hz, nperseg=1000)
    _, h = ss.freqz(gain * b, a, worN=f, fs=m.fs_hz)
    ref = 2 * var / m.fs_hz * np.abs(h) ** 2
    sel = (f > 50) & (f < 4500)
    assert np.sqrt(np.mean((10 * np.log10(p[sel] / ref[sel])) ** 2)) < 1.0


def test_bad_file_names_element(tmp_path, penn_file):
    path, _ = penn_file
    bad = tmp_path / "bad.xml"
    bad.write_text(path.read_text().replace("<numARCoeff>4", "<numARCoeff>5"))
    with pytest.raises(UserError, match=r"bad\.xml: model 1: <ARlsf> has 4"):
        read_penn(bad)


def _toolkit_lsf2poly(lsf: np.ndarray) -> np.ndarray:
    """The toolkit's own LSF-to-polynomial step (AccSynthHashMatrix.cpp, MATLAB's
    lsf2poly), written from its description: even-indexed LSFs are the zeros of the sum
    polynomial (times 1 + z^-1 for even order), odd-indexed the difference's (times
    1 - z^-1; odd order: all of 1 - z^-2 on the difference), A = (P + Q) / 2."""
    z = np.exp(1j * np.asarray(lsf))
    rq, rp = z[0::2], z[1::2]
    q = np.poly(np.concatenate([rq, rq.conj()])).real
    p = np.poly(np.concatenate([rp, rp.conj()])).real
    if lsf.size % 2 == 0:
        return 0.5 * (np.convolve(p, [1, -1]) + np.convolve(q, [1, 1]))[:-1]
    return 0.5 * (np.convolve(p, [1, 0, -1]) + q)[:-1]


@pytest.mark.parametrize("order", [6, 7])
def test_lsf_conversion_matches_the_toolkits(order):
    rng = np.random.default_rng(order)
    lsf = np.sort(rng.uniform(0.05, 3.0, (3, order)), axis=1)
    for row, batch in zip(lsf, lsf_to_poly(lsf), strict=True):
        np.testing.assert_allclose(lsf_to_poly(row), _toolkit_lsf2poly(row), atol=1e-10)
        np.testing.assert_allclose(batch, _toolkit_lsf2poly(row), atol=1e-10)


def test_writer_follows_the_toolkits_layout(penn_file):
    import xml.etree.ElementTree as ET

    path, ms = penn_file
    root = ET.parse(path).getroot()
    m = root.find("model")
    # CreateResampledModels.m's order; ARcoeff and MAcoeff keep the leading 1.
    assert [c.tag for c in m] == ["modNum", "ARcoeff", "ARlsf", "MAcoeff", "MAlsf", "var",
                                  "gain", "speedMod", "forceMod"]
    ar = [float(v.text) for v in m.find("ARcoeff")]
    ma = [float(v.text) for v in m.find("MAcoeff")]
    assert len(ar) == 5 and ar[0] == 1.0 and len(ma) == 3 and ma[0] == 1.0
    np.testing.assert_allclose(ar, lsf_to_poly(ms.ar_lsf[0]))
    assert root.findtext("SpeedUnits") == "mm/s" and root.findtext("ForceUnits") == "N"


def test_ar_only_files_ignore_gain(tmp_path, penn_file):
    """numMACoeff 0: the toolkit reads neither <gain> nor <MAlsf> (LPCModel.cpp)."""
    _, ms = penn_file
    ar_only = PennModelSet("ar", ms.fs_hz, ms.speeds_mm_s, ms.forces_n, ms.tri, ms.ar_lsf,
                           np.zeros((4, 0)), ms.var, np.full(4, 5.0), 400.0, 4.0)
    back = read_penn(write_penn(tmp_path / "ar.xml", ar_only))
    np.testing.assert_array_equal(back.gain, np.ones(4))
    _, b, _, gain = interpolate(back, 100.0, 1.0)
    assert gain == 1.0 and b.tolist() == [1.0]


def test_models_are_indexed_by_the_speed_list(tmp_path, penn_file):
    """<tri> indexes speedList/forceList (the toolkit files each model at the list
    position of its speed and force), whatever the order of the <model> elements."""
    import xml.etree.ElementTree as ET

    path, ms = penn_file
    tree = ET.parse(path)
    root = tree.getroot()
    models = root.findall("model")
    for m in models:
        root.remove(m)
    for m in models[::-1]:
        root.append(m)
    shuffled = tmp_path / "shuffled.xml"
    tree.write(shuffled)
    back = read_penn(shuffled)
    np.testing.assert_allclose(back.ar_lsf, ms.ar_lsf)
    np.testing.assert_allclose(back.speeds_mm_s, ms.speeds_mm_s)
    a, *_ = interpolate(back, 200.0, 0.5)
    np.testing.assert_allclose(a, lsf_to_poly(ms.ar_lsf[1]), atol=1e-10)


@pytest.mark.parametrize(("edit", "message"), [
    (lambda t: t.replace("<var>0.0002</var>", "", 1), r"bad\.xml: model 2: missing element <var>"),
    (lambda t: t.replace("<numARCoeff>4", "<numARCoeff>3"),
     r"bad\.xml: model 1: <ARlsf> has 4 values, <numARCoeff> says 3"),
    (lambda t: t.replace("<value>4</value>", "<value>9</value>", 1),
     r"bad\.xml: <tri> 2: index 9 outside 1\.\.4"),
    (lambda t: t.replace("<value>1</value>", "<value>0</value>", 1),
     r"bad\.xml: <tri> 1: index 0 outside 1\.\.4"),  # 0-based indices are not the toolkit's
    (lambda t: t.replace("<numMod>4", "<numMod>5"), r"bad\.xml: <numMod> says 5, the file has 4"),
    (lambda t: t.replace("<SampleRate>10000.0", "<SampleRate>1e309"),
     r"bad\.xml: <SampleRate> must be a positive finite rate, got inf"),
    (lambda t: t.replace("<speedMod>50.0</speedMod>", "<speedMod>51.0</speedMod>", 1),
     r"bad\.xml: <speedList>/<forceList> value 1 \(50 mm/s, 0.5 N\) has no <model>"),
])
def test_bad_files_name_the_file_and_field(tmp_path, penn_file, edit, message):
    path, _ = penn_file
    text = path.read_text()
    bad = tmp_path / "bad.xml"
    bad.write_text(edit(text))
    assert bad.read_text() != text
    with pytest.raises(UserError, match=message):
        read_penn(bad)


@pytest.mark.parametrize(("old", "new", "message"), [
    ("<numTri>2", "<numTri>two", "<numTri> is not a number"),
    ("<numTri>2", "<numTri>inf", "<numTri> is not a whole number"),
    ("<numMod>4", "<numMod>inf", "<numMod> is not a whole number"),
    ("<numMod>4", "<numMod>4.5", "<numMod> is not a whole number"),
    ("<numARCoeff>4", "<numARCoeff>nan", "<numARCoeff> is not a whole number"),
    ("<numMACoeff>2", "<numMACoeff>-1", "<numMACoeff> is not a whole number"),
])
def test_bad_counts_are_one_line_errors(tmp_path, penn_file, old, new, message):
    path, _ = penn_file
    bad = tmp_path / "bad.xml"
    text = path.read_text()
    assert old in text
    bad.write_text(text.replace(old, new, 1))
    with pytest.raises(UserError, match=rf"bad\.xml: {message}") as e:
        read_penn(bad)
    assert "\n" not in str(e.value)


def test_unknown_units_are_named(tmp_path, penn_file):
    path, _ = penn_file
    odd = tmp_path / "odd.xml"
    odd.write_text(path.read_text().replace("<SpeedUnits>mm/s", "<SpeedUnits>m/s"))
    with pytest.warns(UserWarning, match=r"odd\.xml: <SpeedUnits> is 'm/s'; read as mm/s"):
        read_penn(odd)
