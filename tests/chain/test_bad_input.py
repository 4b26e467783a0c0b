"""Measurements that cannot be trusted are refused with what to check."""

from __future__ import annotations

import numpy as np
import pytest

from fydpad.chain import ChainError
from fydpad.chain.estimate import check_response
from fydpad.chain.identify import identify_entry
from fydpad.chain.measure import check_force
from fydpad.chain.session import open_session
from tests.chain.conftest import BAND_HZ, sim_config


def test_accelerometer_reading_noise_has_too_little_coherence():
    # A part that reads mostly noise (2 m/s^2 rms, ~60x an ADXL345's) at a low level.
    s = open_session(sim_config(noise_m_s2=2.0), "sim", "sim")
    try:
        with pytest.raises(ChainError, match=r"too little coherence to identify.*"
                           r"accelerometer reads the fabric"):
            identify_entry(s, 0.6, 6.0, BAND_HZ, level=0.2, nperseg=256)
    finally:
        s.close()


def test_motors_off_is_a_silent_response(session):
    session.drive.motors.plant.powered = False  # the board's power cut mid-session
    with pytest.raises(ChainError, match=r"response is silent.*motors are powered"):
        identify_entry(session, 0.6, 3.0, BAND_HZ, nperseg=256)


def test_clipped_response_names_the_full_scale():
    y = np.concatenate([np.sin(np.linspace(0, 60, 3000)) * 200.0])
    with pytest.raises(ChainError, match=r"full scale \(156.9 m/s\^2\).*--level"):
        check_response(np.clip(y, -156.9, 156.9), 0.038, 156.9, "k 0.6")


def test_accelerometer_that_stops(tmp_path):
    # A real backend that runs dry: a 0.2 s replay while the plant runs on for 3 s.
    csv = tmp_path / "short.csv"
    t = np.arange(200) / 1000.0
    rows = "\n".join(f"{v:.3f},0.1,0,9.8" for v in t)
    csv.write_text("t_s,ax_m_s2,ay_m_s2,az_m_s2\n" + rows + "\n")
    s = open_session(sim_config(), "sim", f"replay:{csv}")
    s.accel.speed = float("inf")
    try:
        with pytest.raises(ChainError, match=r"accelerometer stopped.*after 200 samples"):
            identify_entry(s, 0.6, 3.0, BAND_HZ, nperseg=256)
    finally:
        s.close()


def test_force_outside_tolerance():
    with pytest.raises(ChainError, match=r"normal force 0.52 \+- 0.0\d N, outside 0.3 \+- 0.1"):
        check_force(np.array([0.5, 0.55, 0.51]), 0.3, 0.1, "k 0.6")
    assert check_force(np.array([0.29, 0.31]), 0.3, 0.1, "k 0.6")[0] == pytest.approx(0.3)


def test_finger_off_the_force_is_refused(session):
    # Asked to hold 0.8 N, the simulated finger eases off to 0.3 N once the run starts.
    from fydpad.chain.measure import press_to_force

    hold = session.hold

    def eased_off(k, force_n):
        theta = hold(k, force_n)
        press_to_force(session.plant, 0.3)
        return theta

    session.hold = eased_off
    with pytest.raises(ChainError, match=r"normal force 0.30 .* outside 0.8 \+- 0.1 N"):
        identify_entry(session, 0.6, 3.0, BAND_HZ, nperseg=256, force_n=0.8,
                       force_tolerance_n=0.1)
