"""The 1-up/1-down staircase of Jiao 2018: convergence with a simulated observer, and
the interactive command driven by piped answers (logged as they come, resumable)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from fydpad.web.staircase import Staircase
from tests.conftest import REPO


def observer(threshold: float, spread: float, rng: np.random.Generator):
    """Says 'real' (rougher) while b is below its threshold, with a logistic spread."""
    def answer(b: float) -> str:
        p_real = 1.0 / (1.0 + np.exp((b - threshold) / spread))
        return "real" if rng.random() < p_real else "virtual"
    return answer


@pytest.mark.parametrize("threshold", [333.0, 470.0, 512.0])
def test_converges_to_the_observers_threshold(threshold):
    results = []
    for seed in range(40):
        ans = observer(threshold, 5.0, np.random.default_rng(seed))
        s = Staircase()
        while not s.done:
            s.answer(ans(s.b))
            assert s.trials < 200
        results.append(s.result)
    r = np.asarray(results)
    # 1-up/1-down converges on the 50 % point; a run is within a couple of steps of it.
    assert abs(np.mean(r) - threshold) < 5.0
    assert np.mean(np.abs(r - threshold) <= 20.0) > 0.9


def test_rules_of_the_paper():
    s = Staircase()
    assert s.b == 400 and s.step == 10
    for a in ["r", "r", "v", "r", "v", "v", "r", "v", "r"]:
        s.answer(a)
    assert s.reversals == [420, 410, 420, 400, 410, 400]
    assert s.done and s.result == pytest.approx((420 + 400 + 410 + 400) / 4)
    with pytest.raises(ValueError):
        s.answer("maybe")


def _cli(tmp_path, answers: str, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "fydpad.cli", "texture", "staircase", "--log",
         str(tmp_path / "log.csv"), *extra], input=answers, capture_output=True, text=True,
        cwd=REPO, timeout=60)


def test_command_logs_as_it_goes_and_resumes(tmp_path):
    first = _cli(tmp_path, "r\nr\nv\nbad\nr\n")  # stdin ends: stopped, resumable
    assert first.returncode == 0, first.stderr
    assert "please answer" in first.stdout
    lines = (tmp_path / "log.csv").read_text().splitlines()
    assert lines[0] == "trial,b,answer,reversal" and len(lines) == 5
    assert lines[1:] == ["1,400,real,0", "2,410,real,0", "3,420,virtual,1", "4,410,real,1"]
    second = _cli(tmp_path, "v\nv\nr\nv\nr\n")
    assert second.returncode == 0, second.stderr
    assert "resumed after 4 trials" in second.stdout
    assert "b = 407.5" in second.stdout  # reversals 420 410 | 420 400 410 400


def test_command_rejects_a_foreign_log(tmp_path):
    (tmp_path / "log.csv").write_text("trial,b,answer,reversal\n1,300,real,0\n")
    r = _cli(tmp_path, "r\n")
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "log.csv: line 2: column 'b'" in r.stderr
