"""Shared helpers of the texture-family tests."""

from __future__ import annotations

import argparse

import numpy as np

from fydpad.commands import texture
from fydpad.synth.texture_scans import DX_MM, TEXTURES, friction_mu_true, friction_params
from fydpad.texture.families.friction import lowpass_position


def run_cli(*argv: str) -> int:
    """``fydpad texture ...`` with the parser registered as the CLI does."""
    parser = argparse.ArgumentParser(prog="fydpad")
    sub = parser.add_subparsers(dest="command")
    texture.register(sub)
    args = parser.parse_args(["texture", *argv])
    return args.func(args)


def truth_in_scan_frame(name: str, scan, cutoff_per_mm: float):
    """The generator's ground-truth mu(x) as the scan records it, band-limited like the
    model: (x_mm grid, mu). The contact lags the tracked hand by F_f / k (the tool's
    tangential compliance, a generator parameter); the model cannot know it, so the
    ground truth is expressed where the recording puts it: at x + lag."""
    k = friction_params(TEXTURES[name]).stiffness_n_per_mm
    lag_mm = float(np.mean(scan.friction_n[1000:-1000])) / k
    mu = friction_mu_true(name)
    a = int(scan.x_mm.min() / DX_MM) - 3000
    b = int(scan.x_mm.max() / DX_MM) + 3000
    seg = lowpass_position(mu[a:b], DX_MM, cutoff_per_mm)
    return (a + np.arange(seg.size)) * DX_MM + lag_mm, seg
