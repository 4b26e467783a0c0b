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
