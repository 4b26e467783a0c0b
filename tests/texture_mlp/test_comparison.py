"""The thesis network against the LPC family on the same held-out test thirds.

Both model the z acceleration of the same strokes (felt; the generator's own force
column, ``friction=True``). The network is the
batch variant (weights in [-0.5, 0.5]) to keep the test fast; docs/texture_mlp.md has
the thesis settings on four textures (``python -m benchmarks.bench_mlp_accuracy``).
"""

from __future__ import annotations

import pytest

from benchmarks.bench_mlp_accuracy import thesis_vs_lpc
from fydpad.texture.families.mlp.train import TrainConfig


@pytest.fixture(scope="module")
def felt():
    return thesis_vs_lpc("felt", TrainConfig(mode="batch", init_range=0.5, max_epochs=300),
                         seconds=8.0)


def test_neither_family_predicts_the_samples(felt):
    """A spectral model draws an independent realisation (R^2 near -1 at equal power);
    the network predicts what (v, delta f) determine, which is little: at most what a
    least-squares fit on the test third itself reaches (measured -0.0004 vs 0.000005)."""
    assert felt["r2_lpc"] < -0.5, felt
    assert felt["r2_mlp"] <= felt["r2_linear_ceiling"] + 0.02, felt


@pytest.mark.xfail(strict=True, reason="felt: PSD correlation 0.073 (network) vs 0.946 "
                   "(LPC), LSD 39.2 vs 2.7 dB")
def test_network_spectrum_is_as_close_as_the_lpc_family(felt):
    assert felt["corr_mlp"] >= felt["corr_lpc"] and felt["lsd_mlp"] <= felt["lsd_lpc"], felt
