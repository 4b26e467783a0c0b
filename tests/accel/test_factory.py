import pytest

from fydpad.accel import open_accelerometer
from fydpad.accel.base import AccelError
from fydpad.accel.replay import ReplayAccelerometer
from fydpad.accel.sim import SimAccelerometer
from fydpad.motors.sim import FabricMotorPlant


def test_specs(tmp_path):
    p = tmp_path / "a.csv"
    p.write_text("t_s,ax_m_s2,ay_m_s2,az_m_s2\n0,0,0,9.8\n0.001,0,0,9.8\n")
    assert isinstance(open_accelerometer(f"replay:{p}"), ReplayAccelerometer)
    assert isinstance(open_accelerometer("sim", FabricMotorPlant()), SimAccelerometer)
    with pytest.raises(AccelError, match="--motors sim"):
        open_accelerometer("sim")
    with pytest.raises(AccelError, match="expected sim"):
        open_accelerometer("usb")
    # serial:PORT[@BAUD] is opened on connect(); tests/accel/test_serial.py runs it
    assert open_accelerometer("serial:/dev/ttyACM0").port == "/dev/ttyACM0"


def test_accel_config_section_round_trips(tmp_path):
    from fydpad.config import StationConfig, config_to_toml, load_config
    cfg = StationConfig()
    cfg.accel.device = "replay:rec/accel.csv"
    cfg.accel.sim_noise_m_s2 = 0.03
    text = config_to_toml(cfg)
    assert "[accel]" in text
    p = tmp_path / "station.toml"
    p.write_text(text)
    back = load_config(p)
    assert back.accel == cfg.accel
