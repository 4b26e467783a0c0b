"""Without the mujoco extra, ``--ur-host sim`` is one clear line (this test needs no
MuJoCo: it hides it when it is installed)."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from teleop.cli import main
from teleop.config import SlaveConfig
from teleop.slaves.ur import URArm


def test_ur_host_sim_without_mujoco_says_what_to_install(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "mujoco", None)  # import mujoco raises ImportError
    arm = URArm(SlaveConfig(ur_host="sim"), retry_wait_s=0.0)
    with pytest.raises(ValueError, match=r"pip install 'fydpad\[mujoco\]'"):
        arm.start(np.array([550.0, 0.0, 250.0]))
    assert main(["slave", "--robot", "ur", "--ur-host", "sim", "--bind", "tcp://127.0.0.1:*",
                 "--rt-priority", "0", "--duration", "0.1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == "teleop slave: --ur-host sim needs MuJoCo: pip install 'fydpad[mujoco]'"
