"""`teleop` command line: help, keys, config loading."""

from __future__ import annotations

import pytest

from teleop.cli import load_config, main


def test_help_lists_the_commands(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert "slave" in out and "keys" in out


def test_keys_generate_writes_pairs_and_authorises_the_client(tmp_path, capsys):
    d = tmp_path / "k"
    assert main(["keys", "generate", str(d)]) == 0
    for f in ("server.key", "server.key_secret", "client.key", "client.key_secret",
              "authorized_clients/client.key"):
        assert (d / f).is_file(), f
    assert oct((d / "server.key_secret").stat().st_mode & 0o777) == "0o600"
    assert main(["keys", "generate", str(d)]) == 2  # never overwrite keys
    assert "refusing to overwrite" in capsys.readouterr().err


def test_config_file_overrides_defaults_and_refuses_unknown_keys(tmp_path):
    p = tmp_path / "t.toml"
    p.write_text("[teleop.safety]\nwatchdog_s = 0.1\nbox_min_mm = [0, 0, 0]\n"
                 "[teleop.mapping]\nrpy_deg = [0, 0, 90]\n")
    cfg = load_config(str(p))
    assert cfg.safety.watchdog_s == 0.1 and cfg.safety.box_min_mm == (0, 0, 0)
    assert cfg.mapping.rpy_deg == (0, 0, 90)
    p.write_text("[safety]\nwatchdgo_s = 1\n")
    with pytest.raises(SystemExit, match=r"unknown key safety\.watchdgo_s"):
        load_config(str(p))


def test_slave_reports_a_bad_endpoint_clearly(capsys):
    assert main(["slave", "--robot", "sim", "--bind", "tcp://999.1.1.1:5", "--curve", "off"]) == 2
    assert "cannot bind tcp://999.1.1.1:5" in capsys.readouterr().err


def test_slave_reads_the_station_device_file(tmp_path):
    """The bundled device file and `fydpad config show`'s layout: [teleop.*] tables taken,
    the station's sections skipped by name, an unknown teleop key still refused."""
    from fydpad.bundled import recordings_dir
    from fydpad.config import StationConfig, config_to_toml

    bundled = load_config(str(recordings_dir() / "device.toml"))
    assert bundled.link.curve == "auto"
    station = StationConfig()
    station.teleop.safety.watchdog_s = 0.15
    station.teleop.link.keys_dir = "lab_keys"
    p = tmp_path / "device.toml"
    p.write_text(config_to_toml(station))
    cfg = load_config(str(p))
    assert cfg.safety.watchdog_s == 0.15 and cfg.link.keys_dir == "lab_keys"
    p.write_text(config_to_toml(station).replace("[teleop.mapping]\n",
                                                 "[teleop.mapping]\nscal = 2\n"))
    with pytest.raises(SystemExit, match=r"unknown key teleop\.mapping\.scal"):
        load_config(str(p))
    p.write_text("[camra]\nx = 1\n[teleop.link]\ncurve = \"on\"\n")
    with pytest.raises(SystemExit, match=r"unknown section \[camra\]"):
        load_config(str(p))


def test_teleop_knows_the_station_sections_by_name():
    """teleop cannot import fydpad: its list of the other sections is kept equal here."""
    import dataclasses

    from fydpad.config import StationConfig
    from teleop.config import OTHER_SECTIONS

    names = {f.name for f in dataclasses.fields(StationConfig)} - {"teleop"}
    assert set(OTHER_SECTIONS) == names


def test_master_socket_takes_host_port_and_says_which_keys_are_missing(tmp_path):
    from teleop.config import LinkConfig
    from teleop.keys import KeyFileMissing
    from teleop.link import MasterSocket

    with MasterSocket("127.0.0.1:5999", LinkConfig(curve="off")) as sock:
        assert sock.endpoint == "tcp://127.0.0.1:5999"
    with pytest.raises(KeyFileMissing) as e:
        MasterSocket("10.0.0.5:5555", LinkConfig(keys_dir=str(tmp_path / "k")))
    message = str(e.value)
    assert "\n" not in message and "client.key_secret not found" in message
    assert f"teleop keys generate {tmp_path / 'k'}" in message
