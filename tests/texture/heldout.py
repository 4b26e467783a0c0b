"""A held-out protocol on the scan generator, shared by the tests
that score a model form on it: held-out 8 s stroke seed 100, second recording seed 200."""

from __future__ import annotations

from fydpad.synth.texture_scans import generate_scan
from fydpad.texture.evaluation.evaluate import evaluate_second
from fydpad.texture.lpc.family import LpcFamily


def held_out(name: str, speed_mm_s: float, model, seconds: float = 8.0, seed: int = 100,
             second_seed: int = 200):
    """(held-out scan, its evaluation mask, the ceiling: a second recording scored
    against it over the same mask)."""
    held = generate_scan(name, speed_mm_s, seconds, seed=seed)
    second = generate_scan(name, speed_mm_s, seconds, seed=second_seed)
    fam = LpcFamily(model)
    mask = fam.covers(held.speed_mm_s)
    return held, mask, evaluate_second(fam, held, second, mask)
