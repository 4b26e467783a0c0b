import numpy as np

from fydpad.accel.sim import LSB_M_S2, SimAccelerometer
from fydpad.motors.sim import FabricMotorPlant


def _drive(plant, n, f_hz=80.0, amp=0.3):
    for k in range(n):
        d = amp * np.sin(2 * np.pi * f_hz * k * plant.config.dt_s)
        plant.set_duty(0.2 + d, 0.2 - d)
        plant.step()


def test_x_axis_is_plant_fabric_accel_quantised():
    plant = FabricMotorPlant()
    with SimAccelerometer(plant) as acc:
        _drive(plant, 300)
        a = acc.read()
        _drive(plant, 200)
        b = acc.read()
    truth = plant.accel_log()
    got = np.vstack([a, b])
    assert got.shape == (500, 4)
    np.testing.assert_array_equal(got[:, 0], truth[:, 0])
    assert np.ptp(truth[:, 1]) > 20 * LSB_M_S2  # the drive really shakes the fabric
    assert np.max(np.abs(got[:, 1] - truth[:, 1])) <= LSB_M_S2 / 2 + 1e-12
    assert np.allclose(got[:, 3], np.round(9.80665 / LSB_M_S2) * LSB_M_S2)
    assert not np.any(got[:, 2])


def test_noise_level():
    plant = FabricMotorPlant()
    with SimAccelerometer(plant, noise_m_s2=0.2, seed=3) as acc:
        plant.step(2000)
        a = acc.read()
    assert abs(np.std(a[:, 2]) - 0.2) < 0.02
