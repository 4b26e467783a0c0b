"""Fixtures shared by the station's tests."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest


@pytest.fixture(scope="module")
def friction_model(tmp_path_factory) -> Path:
    """A friction model (mu(x) one sine period over 10 mm) written as a model file."""
    path = tmp_path_factory.mktemp("model") / "friction.json"
    path.write_text(json.dumps({
        "format": "fydpad-texture-model", "kind": "friction", "format_version": 1,
        "mu": list(0.5 + 0.2 * np.sin(np.linspace(0, 2 * np.pi, 200, endpoint=False))),
        "dx_mm": 0.05, "x0_mm": 0.0}))
    return path
