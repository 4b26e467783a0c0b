"""The simulated fabric and motor plant: softness rendering end to end, the vibration's
resonance, the virtual clock and the fail-safe."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from fydpad.motors.base import MotorConfig, MotorError, MotorPair
from fydpad.motors.drive import MotorDrive, build_drive
from fydpad.motors.pwm import PwmConfig
from fydpad.motors.sim import FabricMotorPlant, SimMotors, indenter_press
from fydpad.softness import SoftnessError, SoftnessWarning, characterise_fabric, fit_through_origin

DEPTHS_MM = np.linspace(0.5, 10.0, 20)


#: Vibration in duty units, so the tests read eq. (3) directly.
UNIT_PWM = PwmConfig(vibration_duty_per_unit=1.0)


def make_drive():
    plant = FabricMotorPlant()
    drive = MotorDrive(SimMotors(plant), pwm=UNIT_PWM)
    drive.start()
    return plant, drive


def run(drive, ticks, vibration=0.0):
    for _ in range(ticks):
        drive.tick(vibration)


def press(plant, drive, rng):
    """The simulated indenter presses while the 1 kHz loop keeps running (10 ticks per
    sample): the dent's extra tension loads the motors and the loop must hold."""
    return indenter_press(plant, DEPTHS_MM, rng, force_noise_n=0.02, depth_noise_mm=0.05,
                          hold=lambda: run(drive, 10))


def test_softness_table_from_simulated_indenter_renders_requested_stiffness():
    rng = np.random.default_rng(11)
    plant, drive = make_drive()
    theta, depth, force = [], [], []
    for th in np.linspace(0.0, 1.2, 7):
        drive.set_theta_rad(th)
        run(drive, 800)
        d, f = press(plant, drive, rng)
        theta += [th] * d.size
        depth += list(d)
        force += list(f)
    table = characterise_fabric(theta, depth, force)
    assert np.all(table.r2 > 0.932)
    lo, hi = table.k_range_n_per_mm
    assert lo < 0.3 and hi > 1.0  # the plant covers the paper's 0.262-1.04 N/mm
    drive.table = table
    errors = []
    for k in (0.3, 0.45, 0.6, 0.75, 0.9, 1.0):
        drive.set_stiffness(k)
        run(drive, 800)
        d, f = press(plant, drive, rng)
        shown = fit_through_origin(d, f).k_n_per_mm
        errors.append(abs(shown - k) / k)
    assert max(errors) < 0.02, errors
    # Nothing saturated while holding the fabric.
    assert drive.composer.vibration_clips == 0
    drive.safe_stop()


def test_request_outside_table_is_clamped_or_refused():
    _plant, drive = make_drive()
    drive.table = characterise_fabric([0, 0, 1, 1], [1, 2, 1, 2], [0.3, 0.6, 0.9, 1.8])
    with pytest.warns(SoftnessWarning):
        assert drive.set_stiffness(5.0) == pytest.approx(1.0)
    with pytest.raises(SoftnessError, match="outside"):
        drive.set_stiffness(5.0, strict=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert drive.set_stiffness(0.6) == pytest.approx(0.5)


def vibration_gain(theta_rad, freq_hz, amp=0.2, seconds=0.25):
    """RMS fabric acceleration per unit vibration duty at one frequency (steady part)."""
    plant, drive = make_drive()
    drive.set_theta_rad(theta_rad)
    run(drive, 600)
    n = int(seconds * 1000)
    acc = np.empty(n)
    for i in range(n):
        drive.tick(amp * np.sin(2 * np.pi * freq_hz * i / 1000.0))
        acc[i] = plant.fabric_accel_m_s2
    return float(np.sqrt(np.mean(acc[n // 2:] ** 2))) / amp, plant


def test_vibration_reaches_fabric_through_a_resonance_that_rises_with_stretch():
    freqs = [60, 100, 150, 200, 250, 300, 400]
    soft = [vibration_gain(0.05, f)[0] for f in freqs]
    stiff = [vibration_gain(1.1, f)[0] for f in freqs]
    soft_peak, stiff_peak = freqs[int(np.argmax(soft))], freqs[int(np.argmax(stiff))]
    # A resonance: the peak stands well above both ends of the band.
    assert max(soft) > 2 * soft[0] and max(soft) > 2 * soft[-1]
    # A stretched fabric is tighter: its resonance is higher.
    assert stiff_peak > soft_peak
    # No vibration, no fabric acceleration beyond the position loop's settling.
    quiet, _ = vibration_gain(0.5, 150, amp=1e-9)
    assert quiet * 1e-9 < 1e-3


def test_virtual_clock_and_step_api():
    plant = FabricMotorPlant()
    plant.set_duty(0.3, 0.3)
    plant.step(250)
    assert plant.t_s == pytest.approx(0.25)
    assert plant.theta_rad[0] > 0.0  # wound up against the fabric
    # The encoder is quantized to its resolution.
    q = 2 * np.pi / plant.config.encoder_counts_per_rev
    assert plant.encoder_rad(0) / q == pytest.approx(round(plant.encoder_rad(0) / q))


def test_unpowered_rollers_return_to_rest_stop():
    plant = FabricMotorPlant()
    plant.reset((0.8, 0.8))
    plant.powered = False
    plant.step(2000)
    assert plant.theta_rad == pytest.approx([0.0, 0.0], abs=1e-9)


def test_context_manager_deactivates_on_exception_and_rests():
    plant = FabricMotorPlant()
    motors = SimMotors(plant)
    assert isinstance(motors, MotorPair)
    with pytest.raises(RuntimeError), motors:
        for _ in range(500):
            motors.set_positions_rad(0.9, 0.9)
        assert plant.theta_rad[0] > 0.5
        raise RuntimeError("fault in the loop")
    assert not motors.active and not plant.powered
    assert plant.theta_rad == pytest.approx([0.0, 0.0], abs=0.02)
    with pytest.raises(MotorError, match="not activated"):
        motors.set_pwm(0.1, 0.1)


def test_safe_stop_turns_vibration_off_and_never_raises():
    plant, drive = make_drive()
    run(drive, 50, vibration=0.2)
    drive.safe_stop()
    assert not drive.composer.vibration_enabled and not plant.powered

    class Broken(SimMotors):
        def deactivate(self):
            raise OSError("port gone")

    d2 = MotorDrive(Broken(FabricMotorPlant()))
    d2.safe_stop()  # must not raise


def test_build_drive_sim_measures_its_own_table_and_nan_means_rest():
    drive = build_drive(MotorConfig(backend="sim"))
    assert drive.table is not None and np.all(drive.table.r2 > 0.932)
    drive.start()
    assert drive.set_stiffness(float("nan")) == pytest.approx(0.0)
    theta = drive.set_stiffness(0.7)
    assert 0.0 < theta < 1.2
    run(drive, 800)
    assert drive.motors.plant.theta_rad[0] == pytest.approx(theta, abs=0.01)
    drive.set_stiffness(float("nan"))
    run(drive, 800)
    assert drive.motors.plant.theta_rad[0] == pytest.approx(0.0, abs=0.01)
    drive.safe_stop()
    with pytest.raises(MotorError, match="backend"):
        build_drive(MotorConfig(backend="usb"))


def test_accel_log_samples_every_tick():
    plant, drive = make_drive()
    plant.enable_accel_log(100)
    run(drive, 150, vibration=0.1)
    log = plant.accel_log()
    assert log.shape == (100, 2)
    np.testing.assert_allclose(np.diff(log[:, 0]), 0.001, rtol=1e-6)
    assert np.any(log[:, 1] != 0.0)


def test_position_mode_adds_vibration_to_the_reference():
    plant = FabricMotorPlant()
    drive = MotorDrive(SimMotors(plant), mode="position", vibration_rad_per_duty=0.02,
                       pwm=UNIT_PWM)
    drive.start()
    drive.set_theta_rad(0.5)
    run(drive, 600)
    refs = drive.tick(0.1)
    # Vibration 0.1 duty -> +-0.002 rad around the reference, opposite on the two motors.
    assert refs[0] - drive.theta_ref_rad == pytest.approx(0.002)
    assert refs[1] - drive.theta_ref_rad == pytest.approx(-0.002)
    assert plant.theta_rad[0] == pytest.approx(0.5, abs=0.01)
    drive.safe_stop()
