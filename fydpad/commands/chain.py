"""``fydpad chain``: identify the actuator chain's transfer function and check its
compensation (Felicetti 2022 sections 3.2-4.1; docs/chain.md)."""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from datetime import UTC, datetime
from pathlib import Path

from fydpad.cli import add_config_argument
from fydpad.errors import UserError
from vision.strict_json import finite


def _floats(text: str, what: str) -> list[float]:
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise UserError(f"{what} {text!r}: expected numbers separated by commas") from None


def _band(text: str) -> tuple[float, float]:
    v = _floats(text, "--band")
    if len(v) != 2:
        raise UserError(f"--band {text!r}: expected LO,HI in Hz")
    return v[0], v[1]


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--motors", choices=["sim", "qb"], default="sim",
                   help="the chain: the simulated fabric and motor plant, or the QB board "
                   "([qb] port of the config) (default: %(default)s)")
    p.add_argument("--accel", metavar="sim|replay:F|serial:PORT[@BAUD]",
                   help="the fabric accelerometer (default: [accel] device of the config, "
                   "'sim': the simulated plant's)")
    p.add_argument("--axis", choices=["x", "y", "z"], default="x",
                   help="accelerometer axis along the fabric's stretch (default: %(default)s)")
    p.add_argument("--sensors", metavar="serial:PORT[@BAUD]",
                   help="with --motors qb: the sensor board whose load cell monitors the force")
    p.add_argument("--force-n", type=float, default=0.3,
                   help="normal force to hold on the fabric, N (Felicetti 2022: %(default)s)")
    p.add_argument("--force-tolerance", type=float, default=0.1, metavar="N",
                   help="refuse a run whose mean force is further off (default: %(default)s)")
    p.add_argument("--seconds", type=float, default=30.0,
                   help="excitation per stiffness, s (default: %(default)s)")
    p.add_argument("--level", type=float, default=0.8,
                   help="drive peak as a share of eq. 3's vibration headroom (default: "
                   "%(default)s; the run is refused if it clips)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random excitation")
    add_config_argument(p)


def check_sentence(fig: dict) -> str:
    """The compensation check's figures as one sentence a person reads."""
    lo, hi = fig["compared_hz"]
    line = (f"At k = {fig['stiffness_n_per_mm']:g} N/mm, over {lo:.0f}-{hi:.0f} Hz "
            f"({fig['compared_bins']} bins): the compensated vibration stays within "
            f"{fig['compensated_max_error_db']:.1f} dB of the target, the uncompensated one "
            f"within {fig['uncompensated_max_error_db']:.1f} dB "
            f"({fig['uncompensated_error_at_resonance_db']:+.1f} dB at the "
            f"{fig['resonance_hz']:.0f} Hz resonance, compensated "
            f"{fig['compensated_error_at_resonance_db']:+.1f} dB)")
    if "offline_max_error_db" in fig:
        line += f"; offline compensation within {fig['offline_max_error_db']:.1f} dB"
    if fig.get("vibration_clips"):
        line += f"; the vibration clipped {fig['vibration_clips']} times"
    return line + "."


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "chain", help="identify the actuator chain's transfer function, check compensation",
        description=(
            "The actuator chain (motors, fabric, finger) shapes the texture vibration the "
            "finger feels. 'identify' measures its transfer function per stiffness setting "
            "(Felicetti 2022 eq. 1: TF = CPSD_yx / PSD_x, Welch, with coherence) into a TF file; "
            "'check' plays a target through the chain with and without compensation and "
            "plots the spectra (Felicetti 2022 Fig. 8). 'fydpad run --compensate TF.npz' "
            "applies the inverse live. See docs/chain.md."),
    )
    ss = p.add_subparsers(dest="chain_command", metavar="ACTION", required=True)
    i = ss.add_parser(
        "identify", help="measure the chain's TF per stiffness into a TF file",
        description=(
            "Drive eq. 3's vibration term with seeded band-limited random noise at each "
            "stiffness while the finger holds --force-n on the fabric (the simulated finger "
            "does on --motors sim; on the device you do, watched by the load cell of "
            "--sensors), record the fabric's acceleration, and estimate TF = CPSD_yx / "
            "PSD_x with Welch averaging and the coherence per frequency. Refused, with what "
            "to check: a response that is silent or clipped, coherence too low, an "
            "accelerometer that stops, a force outside the tolerance, a drive that clips."),
    )
    i.add_argument("--out", metavar="TF.npz", required=True, help="TF file to write")
    i.add_argument("--plot", metavar="PNG", help="draw magnitude, phase and coherence")
    i.add_argument("--stiffness", default="0.45,0.6,0.8,1.0", metavar="LIST",
                   help="stiffness settings, N/mm, comma separated (default: %(default)s)")
    i.add_argument("--band", default="10,450", metavar="LO,HI",
                   help="excitation band, Hz; below 0.9 of the 1 kHz channel's Nyquist "
                   "(default: %(default)s; Felicetti 2022: 10-1000 Hz at audio rate)")
    i.add_argument("--nperseg", type=int, default=512,
                   help="Welch segment length, samples (default: %(default)s)")
    i.add_argument("--yes", action="store_true",
                   help="on the device: do not wait for Enter before each stiffness")
    _common(i)
    i.set_defaults(func=run_identify)
    c = ss.add_parser(
        "check", help="target vs uncompensated vs compensated spectra (Felicetti 2022 Fig. 8)",
        description=(
            "Play a target through the chain at the TF entry nearest --stiffness: "
            "uncompensated (gain-only calibration), compensated by the live minimum-phase "
            "FIR inverse and by the offline FFT inverse (eqs. 2-4); compare the reproduced "
            "PSDs with the target's over the coherent band. Prints the figures (JSON)."),
    )
    c.add_argument("tf", metavar="TF.npz", help="a TF file of 'fydpad chain identify'")
    c.add_argument("--plot", metavar="PNG", help="draw the spectra")
    c.add_argument("--json", metavar="FILE", help="write the figures as JSON")
    c.add_argument("--stiffness", type=float, default=0.6,
                   help="stiffness setting, N/mm (default: %(default)s)")
    c.add_argument("--target", default="band", metavar="band|scan:TEXTURE",
                   help="'band': shaped band-limited noise; 'scan:NAME': a texture's vibration "
                   "from 'fydpad texture generate-scans' (R1, wood_grain, ...) at 30 mm/s")
    _common(c)
    c.set_defaults(func=run_check)


def _session(args, config):
    from fydpad.chain.session import open_session

    return open_session(config, args.motors, args.accel, args.sensors, args.seed)


def _bar(total: int, desc: str):
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="tick", disable=not sys.stderr.isatty(),
                leave=False, dynamic_ncols=True)


def run_identify(args: argparse.Namespace) -> int:
    from fydpad import __version__
    from fydpad.chain.identify import identify_entry, nominal_peak
    from fydpad.chain.plots import plot_tf_set
    from fydpad.chain.tf_file import TfSet, save_tf_set
    from fydpad.config import load_config

    config = load_config(args.config)
    ks = _floats(args.stiffness, "--stiffness")
    band = _band(args.band)
    session = _session(args, config)
    entries = []
    try:
        total = int(len(ks) * args.seconds * session.rate_hz)
        with _bar(total, "identify") as bar:
            for n, k in enumerate(ks):
                if session.plant is None and not args.yes and sys.stdin.isatty():
                    input(f"stiffness {k:g} N/mm: press the fabric with {args.force_n:g} N "
                          "and hold it; Enter to start ")
                t0 = time.perf_counter()
                e = identify_entry(session, k, args.seconds, band, args.level,
                                   args.seed + n, args.nperseg, args.force_n,
                                   args.force_tolerance, args.axis, progress=bar.update)
                entries.append(e)
                force = (f"force {e.force_mean_n:.2f} +- {e.force_sd_n:.2f} N"
                         if math.isfinite(e.force_mean_n) else "force not monitored")
                good = e.estimate.coherent(band)
                print(f"k {k:g} N/mm (theta {e.theta_rad:.3f} rad): {force}; coherence > 0.9 "
                      f"over {int(good.sum())} bins, resonance {nominal_peak(e.estimate, band):.1f}"
                      f" Hz ({time.perf_counter() - t0:.1f} s)", file=sys.stderr)
    finally:
        session.close()
    tfs = TfSet(session.rate_hz, "vibration", band, entries,
                excitation={"kind": "band-limited random", "seconds": args.seconds,
                            "seed": args.seed, "level": args.level, "nperseg": args.nperseg,
                            "force_n": args.force_n},
                provenance={"motors": args.motors, "accel": session.accel_spec,
                            "axis": args.axis, "fydpad": __version__,
                            "vibration_duty_per_unit": config.pwm.vibration_duty_per_unit,
                            "created": datetime.now(UTC).isoformat(
                                timespec="seconds")})
    save_tf_set(tfs, args.out)
    print(f"wrote {args.out} ({len(entries)} stiffness settings)")
    if args.plot:
        plot_tf_set(args.plot, tfs)
        print(f"wrote {args.plot}")
    return 0


def run_check(args: argparse.Namespace) -> int:
    from fydpad.chain.check import band_target, check_compensation, scan_target
    from fydpad.chain.plots import plot_check
    from fydpad.chain.tf_file import load_tf_set
    from fydpad.config import load_config

    config = load_config(args.config)
    rate_hz = config.motors.rate_hz
    tfs = load_tf_set(args.tf, rate_hz, "vibration")
    entry = tfs.nearest(args.stiffness)
    n = int(args.seconds * rate_hz)
    kind, _, name = args.target.partition(":")
    if kind == "band":
        target = band_target(n, rate_hz, tfs.band_hz, args.seed)
    elif kind == "scan" and name:
        target = scan_target(name, 30.0, args.seconds, rate_hz, args.seed)
    else:
        raise UserError(f"--target {args.target!r}: expected band or scan:TEXTURE")
    session = _session(args, config)
    try:
        with _bar(3 * n, "check") as bar:
            res = check_compensation(session, entry, tfs.band_hz, target, args.level,
                                     axis=args.axis, force_n=args.force_n,
                                     progress=bar.update)
    finally:
        session.close()
    print(check_sentence(res.figures))
    if args.json:
        Path(args.json).write_text(
            json.dumps(finite(res.figures), indent=2, allow_nan=False) + "\n")
    if args.plot:
        plot_check(args.plot, res)
        print(f"wrote {args.plot}", file=sys.stderr)
    return 0
