"""Scan reading, model files and bad input: errors name the file and field."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fydpad.errors import UserError
from fydpad.synth.texture_scans import generate_scan, save_generated
from fydpad.texture.lpc.analysis import is_stable
from fydpad.texture.lpc.dft321 import preprocess
from fydpad.texture.lpc.fit import fit_texture
from fydpad.texture.lpc.model_file import load_model, save_model
from fydpad.texture.scan_io import read_scan
from vision.recording import RecordingError


def _write(path, header, rows, comment="# surface=test"):
    path.write_text(comment + "\n" + header + "\n" + "\n".join(rows) + "\n")
    return path


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    d = tmp_path_factory.mktemp("fit")
    paths = []
    for s in (10.0, 30.0):
        scan = generate_scan("canvas", s, 4.0, seed=1)
        paths.append(save_generated(scan, d / f"canvas_{s:g}.csv"))
    scans = [read_scan(p) for p in paths]
    return d, scans, fit_texture(scans, order=200, speeds_mm_s=(10.0, 30.0))


def test_fit_reads_metadata_and_gives_stable_models(fitted):
    _d, scans, model = fitted
    assert scans[0].surface == "canvas" and scans[0].fs_hz == pytest.approx(1000.0)
    assert list(model.speeds_mm_s) == [10.0, 30.0] and model.order == 200
    assert all(is_stable(model.poly(i)) for i in range(2))
    for sc, s2 in zip(scans, model.sigma2, strict=True):  # a prediction gain at each speed
        assert s2 < np.mean(preprocess(sc.acc, sc.fs_hz) ** 2)


def test_a_surface_name_with_spaces_is_read_whole(tmp_path):
    """``# surface=Floortile 1``: the value runs to the next ``key=``, so surfaces that share
    a first word stay apart (identify and compare label and group scans by it)."""
    from fydpad.texture.evaluation.identify import by_surface
    from fydpad.texture.scan_io import write_scan

    scan = generate_scan("canvas", 20.0, 1.0, seed=1)
    for name in ("Floortile 1", "Floortile 3"):
        write_scan(tmp_path / f"{name}.csv", scan.t_s, scan.acc, scan.speed_mm_s,
                   meta={"surface": name, "tool": "3d-printed tip", "speed_mm_s": 20})
    scans = [read_scan(tmp_path / f"{n}.csv") for n in ("Floortile 1", "Floortile 3")]
    assert [sc.surface for sc in scans] == ["Floortile 1", "Floortile 3"]
    assert scans[0].meta == {"surface": "Floortile 1", "tool": "3d-printed tip",
                             "speed_mm_s": "20"}
    assert list(by_surface(scans)) == ["Floortile 1", "Floortile 3"]
    p = _write(tmp_path / "c.csv", "t_s,ax,ay,az,speed_mm_s",
               [f"{k / 1000},0,0,{(-1) ** k},20" for k in range(64)],
               comment="# surface=SS1 tool=3d-printed-tip\n# notes by hand, then rig=B 2")
    assert read_scan(p).meta == {"surface": "SS1", "tool": "3d-printed-tip", "rig": "B 2"}


def test_model_round_trip_and_version(fitted, tmp_path):
    _, _, model = fitted
    p = save_model(model, tmp_path / "m.json")
    back = load_model(p)
    np.testing.assert_allclose(back.h, model.h)
    np.testing.assert_allclose(back.sigma2, model.sigma2)
    data = json.loads(p.read_text())
    data["format_version"] = 99
    (tmp_path / "v.json").write_text(json.dumps(data))
    with pytest.raises(UserError, match=r"v\.json.*format_version"):
        load_model(tmp_path / "v.json")
    data["format_version"] = 1
    data["models"][0]["h"] = [2.5] + [0.0] * 199
    (tmp_path / "u.json").write_text(json.dumps(data))
    with pytest.raises(UserError, match=r"u\.json: models\[0\].*unstable"):
        load_model(tmp_path / "u.json")


def test_too_short_for_order(tmp_path):
    scan = generate_scan("felt", 20.0, 0.6, seed=1)
    with pytest.raises(UserError, match="order-200"):
        fit_texture([scan], order=200, speeds_mm_s=(20.0,))


def test_a_speed_too_short_for_the_order_is_skipped_and_said():
    """0.6 s at 10 mm/s (under 4 x order samples) beside 4 s at 20 and 30 mm/s: the model
    has 20 and 30 mm/s, the warning names 10 mm/s and the order."""
    scans = [generate_scan("felt", 20.0, 4.0, seed=1), generate_scan("felt", 30.0, 4.0, seed=1),
             generate_scan("felt", 10.0, 0.6, seed=2)]
    with pytest.warns(UserWarning, match=r"near 10 mm/s for an order-200 model.*no model"):
        model = fit_texture(scans, order=200, speeds_mm_s=(10.0, 20.0, 30.0))
    assert list(model.speeds_mm_s) == [20.0, 30.0]


def test_uneven_time_missing_speed_and_nan(tmp_path):
    rows = [f"{k * 0.001:.3f},0,0,1,20" for k in range(50)]
    rows[20] = "0.0205,0,0,1,20"
    with pytest.raises(RecordingError, match=r"uneven.*line 2[23]|line 2[23].*uneven"):
        read_scan(_write(tmp_path / "u.csv", "t_s,ax,ay,az,speed_mm_s", rows))
    rows = [f"{k * 0.001:.3f},0,0,1" for k in range(50)]
    with pytest.raises(RecordingError, match=r"n\.csv.*speed_mm_s"):
        read_scan(_write(tmp_path / "n.csv", "t_s,ax,ay,az", rows))
    rows = [f"{k * 0.001:.3f},0,0,1,20" for k in range(50)]
    rows[10] = "0.010,nan,0,1,20"
    with pytest.raises(RecordingError, match=r"line 13: column 'ax'"):
        read_scan(_write(tmp_path / "nan.csv", "t_s,ax,ay,az,speed_mm_s", rows))


def test_speed_from_position_when_no_speed_column(tmp_path):
    rows = [f"{k * 0.001:.3f},0,0,1,{20 * k * 0.001:.4f},0" for k in range(2000)]
    scan = read_scan(_write(tmp_path / "p.csv", "t_s,ax,ay,az,x_mm,y_mm", rows))
    assert np.median(scan.speed_mm_s) == pytest.approx(20.0, rel=0.01)
