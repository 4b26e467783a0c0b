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
