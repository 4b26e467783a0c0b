"""The experiment results folder (--web-results) appears only with the first result,
and its path is printed then; a station with the web view writes nothing into the
current directory before that."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from fydpad.web.experiment import ExperimentSession

REPO = Path(__file__).resolve().parents[2]


def test_the_first_session_creates_the_folder_and_says_where(tmp_path, capsys):
    results = tmp_path / "results"
    ExperimentSession.open(results, "p01", seed=1)
    assert (results / "p01.json").is_file()
    assert f"experiment results: {results.resolve()}" in capsys.readouterr().err
    ExperimentSession.open(results, "p02", seed=2)
    assert "experiment results" not in capsys.readouterr().err  # said once, when made


def test_a_replay_with_the_web_view_leaves_no_results_folder(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(REPO), "XDG_CACHE_HOME": str(tmp_path / "cache")}
    proc = subprocess.run(
        [sys.executable, "-m", "fydpad.cli", "run", "--replay", str(REPO / "recordings" / "circle"),
         "--duration", "1", "--web", "0"], cwd=tmp_path,
        env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert not (tmp_path / "experiment-results").exists()
    assert "experiment results" not in proc.stderr
    # The stimuli's grating models went to the cache instead.
    assert sorted(p.name for p in (tmp_path / "cache" / "fydpad" / "textures").iterdir())
