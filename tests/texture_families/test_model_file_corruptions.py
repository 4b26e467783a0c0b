"""Any single-key corruption of a friction, grating or MLP model file is either a file
that renders or a one-line UserError naming the file: never another exception (a model
file is input a user may have edited by hand)."""

from __future__ import annotations

import copy
import json
import warnings
from collections.abc import Iterator

import pytest

from fydpad.errors import UserError
from fydpad.synth.texture_scans import generate_scan
from fydpad.texture.families import fit_family, load_family
from fydpad.texture.family import constant_stroke

BAD_VALUES = (None, "x", [], {}, -1, 0, True, [1, "a"], [[1]], 1e300, -1e300, "absent")


def _key_paths(obj, prefix=()) -> Iterator[tuple]:
    """Every key and (short) list index path below ``obj``."""
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield (*prefix, k)
            yield from _key_paths(v, (*prefix, k))
    elif isinstance(obj, list) and len(obj) < 6:
        for i, v in enumerate(obj):
            yield (*prefix, i)
            yield from _key_paths(v, (*prefix, i))


@pytest.fixture(scope="module")
def model_files():
    scans = [generate_scan("canvas", v, 3.0, seed=1, friction=True) for v in (10.0, 30.0)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return {"friction": fit_family("friction", scans[:1]),
                "grating": fit_family("grating", None, wavelength_mm=2.15),
                "mlp": fit_family("mlp", scans, max_epochs=5, mode="batch")}


@pytest.mark.parametrize("kind", ["friction", "grating", "mlp"])
def test_every_single_key_corruption_renders_or_is_a_user_error(model_files, tmp_path, kind):
    data = model_files[kind]
    path = tmp_path / f"{kind}.json"
    outcomes = {"renders": 0, "refused": 0}
    for keys in _key_paths(data):
        if keys[0] in ("format", "provenance"):
            continue
        for bad in BAD_VALUES:
            edited = copy.deepcopy(data)
            parent = edited
            for k in keys[:-1]:
                parent = parent[k]
            if bad == "absent":
                if not isinstance(parent, dict):
                    continue
                del parent[keys[-1]]
            else:
                parent[keys[-1]] = bad
            path.write_text(json.dumps(edited))
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    fam = load_family(str(path))
                    for channel, rate in fam.channels.items():
                        fam.render(constant_stroke(20.0, 0.05, rate), channel)
                    fam.prepare(1000.0)
                    for k in range(20):
                        fam.tick(k / 1000, True, 1.0 + 0.02 * k, 0.0, 20.0, 1.0)
                outcomes["renders"] += 1
            except UserError as exc:
                assert str(path) in str(exc), (keys, bad, str(exc))
                outcomes["refused"] += 1
            except Exception as exc:  # the failure this test looks for
                pytest.fail(f"{kind} file with {'.'.join(map(str, keys))} = {bad!r}: "
                            f"{type(exc).__name__}: {exc}")
    assert outcomes["refused"] > 50 and outcomes["renders"] > 10, outcomes
