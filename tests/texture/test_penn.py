"""Penn Haptic Texture Toolkit import, on a small file in its schema written here."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as ss

from fydpad.errors import UserError
from fydpad.texture.lpc import reflection_to_poly
from fydpad.texture.lsf import lsf_to_poly, poly_to_lsf
from fydpad.texture.penn import PennModelSet, PennRenderer, interpolate, read_penn, write_penn


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
    r.render(50.0, 0.5, 0.2, fs_out_hz=m.fs_hz)
    y = r.render(50.0, 0.5, 20.0, fs_out_hz=m.fs_hz)
    a, b, var, gain = interpolate(m, 50.0, 0.5)
    f, p = ss.welch(y, m.fs_hz, nperseg=1000)
    _, h = ss.freqz(gain * b, a, worN=f, fs=m.fs_hz)
    ref = 2 * var / m.fs_hz * np.abs(h) ** 2
    sel = (f > 50) & (f < 4500)
    assert np.sqrt(np.mean((10 * np.log10(p[sel] / ref[sel])) ** 2)) < 1.0
    assert r.render(100.0, 1.0, 1.0, fs_out_hz=1000.0).size == 1000


def test_bad_file_names_element(tmp_path, penn_file):
    path, _ = penn_file
    bad = tmp_path / "bad.xml"
    bad.write_text(path.read_text().replace("<numARCoeff>4", "<numARCoeff>5"))
    with pytest.raises(UserError, match=r"bad\.xml: model 1: <ARlsf> has 4"):
        read_penn(bad)
