"""`fydpad calibrate ir|force --example DIR` write a sample input; the calibration run
on it recovers the device the sample was made from."""

from __future__ import annotations

import numpy as np
import pytest

from fydpad.calibration_examples import (
    FORCE_GAIN_N_PER_COUNT,
    FORCE_OFFSET_COUNTS,
    example_ir_volts,
)
from fydpad.cli import main
from fydpad.config import load_config
from tests.ir_curve import voltage_to_distance_mm


def test_ir_example_fits_back_to_its_sensors(tmp_path, capsys):
    assert main(["calibrate", "ir", "--example", str(tmp_path)]) == 0
    assert "fydpad calibrate ir" in capsys.readouterr().out
    out = tmp_path / "ir.toml"
    assert main(["calibrate", "ir", str(tmp_path / "ir_pairs.csv"), "--out", str(out)]) == 0
    ir = load_config(out).ir
    d = np.arange(60.0, 281.0, 5.0)  # inside the measured 40-300 mm
    for sensor in range(3):
        fitted = voltage_to_distance_mm(example_ir_volts(d, sensor), ir.poly_cm[sensor],
                                        ir.valid_range_v[sensor])
        rms = np.sqrt(np.nanmean((fitted - d) ** 2))
        assert rms < 3.0, (sensor, rms)  # against the sensor's true curve
    # The sensors differ by 4-5 %: one shared curve would be off by far more.
    shared = voltage_to_distance_mm(example_ir_volts(d, 2), ir.poly_cm[0], ir.valid_range_v[0])
    assert np.sqrt(np.nanmean((shared - d) ** 2)) > 6.0


def test_force_example_fits_back_to_its_load_cell(tmp_path):
    assert main(["calibrate", "force", "--example", str(tmp_path)]) == 0
    out = tmp_path / "force.toml"
    assert main(["calibrate", "force", str(tmp_path / "force_weights.csv"),
                 "--out", str(out)]) == 0
    force = load_config(out).force
    assert force.gain_n_per_count == pytest.approx(FORCE_GAIN_N_PER_COUNT, rel=0.005)
    assert force.offset_counts == pytest.approx(FORCE_OFFSET_COUNTS, abs=30)


def test_no_data_and_no_example_is_one_line(capsys):
    assert main(["calibrate", "force"]) == 2
    assert "--example DIR" in capsys.readouterr().err


def test_camera_example_fits_back_to_its_lens(tmp_path, capsys):
    """The board views rendered through the example lens give back that lens: its focal
    length and centre, and its distortion correction (up to 63 px at the corners) within
    0.5 px RMS over the whole 640x480 view."""
    import cv2

    from fydpad.calibration_examples import CHARUCO_VIEWS, LENS_DIST, LENS_K

    assert main(["calibrate", "camera", "--example", str(tmp_path)]) == 0
    assert len(list((tmp_path / "charuco").glob("view_*.png"))) == CHARUCO_VIEWS
    out = tmp_path / "camera.toml"
    assert main(["calibrate", "camera", str(tmp_path / "charuco"), "--out", str(out)]) == 0
    assert f"from {CHARUCO_VIEWS} board views" in capsys.readouterr().out
    intr = load_config(out).camera.intrinsics
    assert intr.rms_px < 0.3
    np.testing.assert_allclose(np.diag(intr.k)[:2], np.diag(LENS_K)[:2], rtol=0.005)
    np.testing.assert_allclose(intr.k[:2, 2], LENS_K[:2, 2], atol=2.0)
    uu, vv = np.meshgrid(np.linspace(0, 639, 17), np.linspace(0, 479, 13))
    pix = np.stack([uu.ravel(), vv.ravel()], axis=1).reshape(-1, 1, 2)
    true = cv2.undistortPoints(pix, LENS_K, LENS_DIST, P=LENS_K).reshape(-1, 2)
    fitted = cv2.undistortPoints(pix, intr.k, intr.dist, P=intr.k).reshape(-1, 2)
    shift = true - pix.reshape(-1, 2)
    assert np.max(np.hypot(*shift.T)) > 30  # the lens bends the corners by tens of pixels
    # Each model's correction in its own ideal camera: the same field, pixel for pixel.
    miss = np.hypot(*(fitted - true).T)
    assert np.sqrt(np.mean(miss ** 2)) < 0.5 and np.max(miss) < 3.0, miss


def test_softness_example_fits_back_to_the_simulated_fabric(tmp_path, capsys):
    from fydpad.calibration_examples import SOFTNESS_DEPTHS_MM, SOFTNESS_THETAS_RAD
    from fydpad.fabric import Fabric
    from fydpad.softness import load_table

    assert main(["softness", "calibrate", "--example", str(tmp_path)]) == 0
    table_path = tmp_path / "table.csv"
    assert main(["softness", "calibrate", str(tmp_path / "softness_indenter.csv"),
                 "--out", str(table_path)]) == 0
    table = load_table(table_path)
    fabric = Fabric()
    d = SOFTNESS_DEPTHS_MM
    for theta, k in zip(table.theta_rad, table.k_n_per_mm, strict=True):
        tension = fabric.tension_n(fabric.stretch_mm(theta, theta))
        f = fabric.force_n(d, tension)
        k_true = float(d @ f / (d @ d))  # the noise-free slope through the origin
        assert k == pytest.approx(k_true, rel=0.02), theta
        # The small-dent stiffness (the dent's cubic stiffening adds ~2 % over 0-5 mm).
        assert k == pytest.approx(fabric.stiffness_at_theta(theta), rel=0.04), theta
    np.testing.assert_allclose(table.theta_rad, SOFTNESS_THETAS_RAD, atol=1e-4)


def test_specimen_example_fits_back_to_its_lambdas(tmp_path, capsys):
    from fydpad.calibration_examples import SPECIMEN_LAMBDAS

    assert main(["softness", "fit-specimen", "--example", str(tmp_path)]) == 0
    capsys.readouterr()
    for name, lam in SPECIMEN_LAMBDAS.items():
        assert main(["softness", "fit-specimen", str(tmp_path / f"specimen_{name}.csv")]) == 0
        out = capsys.readouterr().out
        fitted = float(out.split("lambda = ")[1].split()[0])
        assert fitted == pytest.approx(lam, rel=0.02), out
    assert "nearest paper specimen SS3" in out  # S2's lambda is SS3's and SS4's


def test_camera_and_softness_without_input_say_so(capsys):
    assert main(["calibrate", "camera"]) == 2
    assert main(["softness", "calibrate"]) == 2
    assert main(["softness", "fit-specimen"]) == 2
    err = capsys.readouterr().err
    assert err.count("--example DIR") == 3
