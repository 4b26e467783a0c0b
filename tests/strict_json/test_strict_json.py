"""Every JSON the project writes is strict (RFC 8259): no NaN or Infinity, null for a
missing value. fydpad/texture/ is checked by its own tests."""

from __future__ import annotations

import ast
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from vision.strict_json import finite

REPO = Path(__file__).resolve().parents[2]
CHECKED = ("fydpad", "vision", "teleop", "benchmarks", "recordings")


def strict_loads(text: str):
    """json.loads refusing NaN, Infinity and -Infinity, as JSON.parse does."""
    def refuse(name: str):
        raise ValueError(f"not JSON: {name}")

    return json.loads(text, parse_constant=refuse)


def json_writes() -> list[tuple[Path, int, bool]]:
    """Every json.dump / json.dumps call: (file, line, has allow_nan=False)."""
    calls = []
    for top in CHECKED:
        for path in sorted((REPO / top).rglob("*.py")):
            if path.relative_to(REPO).parts[:2] == ("fydpad", "texture"):
                continue
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                        and node.func.attr in ("dump", "dumps")
                        and isinstance(node.func.value, ast.Name)
                        and node.func.value.id == "json"):
                    strict = any(k.arg == "allow_nan" and isinstance(k.value, ast.Constant)
                                 and k.value.value is False for k in node.keywords)
                    calls.append((path.relative_to(REPO), node.lineno, strict))
    return calls


def test_every_json_write_refuses_nan():
    calls = json_writes()
    assert len(calls) > 10  # the walk found the project's writers
    loose = [f"{p}:{line}" for p, line, strict in calls if not strict]
    assert not loose, f"json.dump(s) without allow_nan=False: {loose}"


def test_finite_writes_null_for_missing_values():
    data = {"a": math.nan, "b": [1.0, math.inf, np.float64("nan")], "c": np.array([2.0, np.nan]),
            "d": (np.int64(3), -math.inf), "e": "NaN"}
    text = json.dumps(finite(data), allow_nan=False)
    assert strict_loads(text) == {"a": None, "b": [1.0, None, None], "c": [2.0, None],
                                  "d": [3, None], "e": "NaN"}
    with pytest.raises(ValueError):
        strict_loads('{"x": NaN}')  # the parser used here is strict


def test_station_stats_are_strict_json(tmp_path):
    """A replay without IR: indentation, force and stiffness have no value (NaN inside)."""
    stats = tmp_path / "s.json"
    proc = subprocess.run(
        [sys.executable, "-m", "fydpad.cli", "run", "--replay", str(REPO / "recordings" / "circle"),
         "--duration", "1.5", "--stats", str(stats)],
        cwd=tmp_path, capture_output=True, text=True, timeout=120,
        env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"})
    assert proc.returncode == 0, proc.stderr
    text = stats.read_text()
    data = strict_loads(text)
    assert "render" in data
    assert "null" in text  # a value the run did not have is written as null
