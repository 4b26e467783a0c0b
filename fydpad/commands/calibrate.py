"""``fydpad calibrate``: one sub-subcommand per thing to calibrate.

``ir`` refits eq. (1) per IR sensor from (distance, voltage) pairs; ``indentation`` fits
the correction beyond the plane from recordings of presses of known depth; ``force``
fits the load cell's offset and gain from known weights (docs/calibration_files.md).
``camera``
and ``workspace`` come from ``fydpad.commands.calibrate_vision`` when it is there. To
add one, put its ``register(sub)`` in ``SUBCOMMANDS``.
"""

from __future__ import annotations

# Libraries are imported inside the command functions, so that --help starts fast.
import argparse
import importlib
import importlib.util
from collections.abc import Callable
from dataclasses import replace
from datetime import date
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fydpad.cli import add_truncation_argument
from fydpad.errors import UserError

if TYPE_CHECKING:  # annotations only: the modules load inside the functions
    import numpy as np

    from vision.config import IRConfig
    from vision.force import ForceCalibration
    from vision.indentation import IRFit

Register = Callable[[argparse._SubParsersAction], None]


def register_ir(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "ir",
        help="refit the IR sensors' distance polynomial (eq. 1) from measured pairs",
        description=(
            "Refit eq. (1), the 5th-order polynomial from voltage to distance, for each IR "
            "sensor from a CSV of (distance, voltage) pairs: header distance_mm,v0,v1,v2 "
            "(a sensor's column may be absent, or a cell empty where it was not measured; "
            "see docs/calibration_files.md). Prints R^2 and the RMS residual per sensor and "
            "writes the [ir] section (poly_cm, valid_range_v: a fit is valid only over the "
            "voltages it was fitted on)."
        ),
    )
    p.add_argument("data", metavar="DATA.csv", nargs="?", help="distance_mm,v0,v1,v2 pairs")
    p.add_argument("--example", metavar="DIR",
                   help="write a sample input (DIR/ir_pairs.csv: three sensors off the "
                   "paper's curve by a few percent, with noise) and say how to fit it")
    p.add_argument("--out", metavar="TOML", help="configuration file to write (default: print)")
    p.add_argument("--plot", metavar="PNG", help="draw the data, the fits and the residuals")
    p.add_argument("--degree", type=int, default=5, help="polynomial degree (default: 5)")
    p.set_defaults(func=run_ir)


def register_force(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "force",
        help="the load cell's offset and gain from readings under known weights",
        description=(
            "Fit force_n = gain * (raw - offset) to raw load cell readings under known "
            "weights: a CSV with header mass_g,raw, one row per reading (repeat readings "
            "of a weight are welcome; include 0 g, the empty cell). Weights must be within "
            "the cell's 780 g. Prints the fit, R^2 and residuals and writes the [force] "
            "section."
        ),
    )
    p.add_argument("data", metavar="DATA.csv", nargs="?", help="mass_g,raw readings")
    p.add_argument("--example", metavar="DIR",
                   help="write a sample input (DIR/force_weights.csv: readings under six "
                   "weights, with noise) and say how to fit it")
    p.add_argument("--out", metavar="TOML", help="configuration file to write (default: print)")
    p.add_argument("--plot", metavar="PNG", help="draw the readings, the fit and residuals")
    p.add_argument("--full-scale-g", type=float, default=780.0,
                   help="the load cell's rated capacity (default: 780 g, CZL616C)")
    p.set_defaults(func=run_force)


def register_indentation(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "indentation",
        help="fit the indentation correction beyond the plane from presses of known depth",
        description=(
            "Fit the correction beyond eq. (2)'s plane (docs/indentation.md) from pad "
            "session recordings that have ir.csv and truth.csv (presses of known depth: an "
            "indenter, or the synthetic pad). The truth's contact and centroid are used, so "
            "the fit concerns the indentation alone. Prints the plane's RMSE and the "
            "corrected one on held-out presses (each press scored by the fit on the others; "
            "the ridge chosen by that score), and writes "
            "correction_coef into the [ir] section. The correction weighs each sensor's "
            "deflection by a polynomial of the contact's position, so a fit on presses "
            "holds for strokes. --protocol prints the 2-minute session to record "
            "(the web view's /indentation-guide walks through it)."
        ),
    )
    p.add_argument("recdirs", nargs="*", metavar="RECDIR", help="recordings with truth.csv")
    p.add_argument("--protocol", action="store_true",
                   help="print the calibration protocol (which presses, where, how deep) "
                        "and exit")
    p.add_argument("--out", metavar="TOML", help="configuration file to write (default: print)")
    p.add_argument("--xy-degree", type=int, default=3,
                   help="degree in the centroid position (default: 3)")
    p.add_argument("--depth-degree", type=int, default=2,
                   help="degree in the sensors' deflections (default: 2)")
    add_truncation_argument(p)
    p.set_defaults(func=run_indentation)


def _vision_register(name: str) -> Register | None:
    """``calibrate_vision.register_<name>`` when that module has landed."""
    module = "fydpad.commands.calibrate_vision"
    if importlib.util.find_spec(module) is None:
        return None
    return getattr(importlib.import_module(module), f"register_{name}", None)


#: Sub-subcommands in ``--help`` order: name -> ``register(sub)``, or a function that
#: finds it (None when that part of the project has not landed).
SUBCOMMANDS: dict[str, Register | Callable[[], Register | None]] = {
    "ir": register_ir,
    "indentation": register_indentation,
    "force": register_force,
    "camera": lambda: _vision_register("camera"),
    "workspace": lambda: _vision_register("workspace"),
}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "calibrate",
        help="calibrate the IR sensors, the load cell, the camera or the workspace",
        description="Calibrate one part of the device; the result goes into the "
        "configuration (TOML). Run 'fydpad calibrate WHAT --help' for each.",
    )
    inner = p.add_subparsers(dest="calibrate_what", metavar="WHAT", required=True)
    for name, entry in SUBCOMMANDS.items():
        if name in ("ir", "indentation", "force"):
            entry(inner)  # type: ignore[call-arg]
            continue
        found = entry()  # type: ignore[call-arg]
        if found is not None:
            found(inner)


# --------------------------------------------------------------------------- common


def _line_numbers(path: Path) -> list[int]:
    """File line of each data row, as ``read_csv_columns`` reads them (comments before
    the header and blank rows skipped), so errors can name the line."""
    lines: list[int] = []
    header_seen = False
    with path.open(encoding="utf-8") as fh:
        for no, text in enumerate(fh, start=1):
            if not header_seen:
                if text.lstrip().startswith("#"):
                    continue
                header_seen = True
                continue
            if not text.strip():
                continue
            lines.append(no)
    return lines


def _load_config(args: argparse.Namespace) -> Any | None:
    """The device configuration when ``fydpad.config`` knows this section, else None."""
    from fydpad.config import load_config

    return load_config(getattr(args, "config", None))


def _write_section(
    args: argparse.Namespace, section: str, values: dict[str, Any], comments: list[str],
) -> str:
    """Into the whole configuration when it has ``section`` (written with the project's
    TOML writer), else as a standalone ``[section]`` table to merge by hand."""
    from fydpad.config import config_to_toml

    config = _load_config(args)
    if config is not None and hasattr(config, section):
        setattr(config, section, replace(getattr(config, section), **values))
        body = config_to_toml(config)
    else:
        body = f"[{section}]\n" + "".join(f"{k} = {_toml(v)}\n" for k, v in values.items())
    text = "".join(f"# {c}\n" for c in comments) + body
    if args.out:
        try:
            Path(args.out).write_text(text, encoding="utf-8")
        except OSError as exc:
            raise UserError(f"{args.out}: cannot write ({exc.strerror})") from None
        print(f"written to {args.out} [{section}]")
    else:
        print(text, end="")
    return text


def _toml(v: Any) -> str:
    if isinstance(v, tuple | list):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    if isinstance(v, bool):
        return "true" if v else "false"
    return repr(float(v)) if isinstance(v, float) else repr(v)


# --------------------------------------------------------------------------- ir


def _example(args: argparse.Namespace, command: str, write: Callable[[Path], Path]) -> bool:
    """--example DIR: write the sample input and say what to run on it (True), or check a
    data file was given (False)."""
    if args.example:
        path = write(Path(args.example))
        print(f"wrote {path}: fit it with `fydpad calibrate {command} {path}`")
        return True
    if args.data is None:
        raise UserError(f"calibrate {command}: give DATA.csv (or --example DIR for a sample)")
    return False


def run_ir(args: argparse.Namespace) -> int:
    import numpy as np

    from fydpad.calibration_examples import write_ir_example
    from vision.config import IRConfig
    from vision.indentation import IRCalibrationError, fit_ir_polynomial
    from vision.recording import read_csv_columns

    if _example(args, "ir", write_ir_example):
        return 0
    path = Path(args.data)
    cols = read_csv_columns(path, ("distance_mm",), optional=("v0", "v1", "v2"),
                            empty_ok=("v0", "v1", "v2"))
    sensors = [i for i in range(3) if f"v{i}" in cols]
    if not sensors:
        raise UserError(f"{path}: line 1: no voltage column (expected v0, v1 and/or v2)")
    lines = _line_numbers(path)
    d = cols["distance_mm"]
    bad = np.flatnonzero(d <= 0)
    if bad.size:
        raise UserError(f"{path}: line {lines[bad[0]]}: distance_mm must be positive")
    for i in sensors:
        v = cols[f"v{i}"]
        bad = np.flatnonzero((v <= 0) | (v > 5.5))
        if bad.size:
            raise UserError(f"{path}: line {lines[bad[0]]}: column 'v{i}': {v[bad[0]]:g} V is "
                            "not a sensor voltage (0-5 V)")
    if args.degree < 1:
        raise UserError("--degree must be at least 1")
    fits: dict[int, IRFit] = {}
    for i in sensors:
        try:
            fits[i] = fit_ir_polynomial(d, cols[f"v{i}"], args.degree)
        except IRCalibrationError as exc:
            raise UserError(f"{path}: column 'v{i}': {exc}") from None
    config = _load_config(args)
    base: IRConfig = getattr(config, "ir", None) or IRConfig()
    poly = [list(p) for p in base.poly_cm]
    ranges = [list(r) for r in base.valid_range_v]
    comments = [f"fydpad calibrate ir {path.name} ({date.today().isoformat()})"]
    for i, fit in fits.items():
        poly[i], ranges[i] = list(fit.poly_cm), list(fit.valid_range_v)
        summary = (f"sensor {i}: {fit.n_points} points, R^2 {fit.r2:.5f}, RMS residual "
                   f"{fit.rms_mm:.2f} mm, valid {fit.valid_range_v[0]:.3f}-"
                   f"{fit.valid_range_v[1]:.3f} V")
        print(summary)
        comments.append(summary)
        if not fit.monotonic:
            warn = (f"sensor {i}: warning: the fit does not fall monotonically over its "
                    "range; two distances read alike there (measure more points)")
            print(warn)
            comments.append(warn)
    if args.plot:
        _plot_ir(args.plot, d, cols, fits)
    _write_section(args, "ir", {
        "poly_cm": tuple(tuple(p) for p in poly),
        "valid_range_v": tuple(tuple(r) for r in ranges),
    }, comments)
    return 0


def _plot_ir(path: str, d_mm: np.ndarray, cols: dict[str, np.ndarray],
             fits: dict[int, IRFit]) -> None:
    import numpy as np

    from fydpad.plots import plt
    from vision.ir import PAPER_POLY_CM

    fig, (ax, axr) = plt.subplots(2, 1, figsize=(8, 7), sharex=True,
                                  gridspec_kw={"height_ratios": (2, 1)}, constrained_layout=True)
    grid = np.linspace(0.42, 2.75, 300)
    ax.plot(grid, np.polyval(PAPER_POLY_CM, grid) * 10, "k--", lw=1, label="paper eq. (1)")
    for i, fit in fits.items():
        v = cols[f"v{i}"]
        g = np.linspace(*fit.valid_range_v, 300)
        (line,) = ax.plot(g, np.polyval(fit.poly_cm, g) * 10, label=f"sensor {i} fit "
                          f"(R$^2$ {fit.r2:.4f})")
        ax.plot(v, d_mm, ".", color=line.get_color(), ms=4)
        axr.plot(v, d_mm - np.polyval(fit.poly_cm, v) * 10, ".", color=line.get_color(), ms=4)
    ax.set_ylabel("distance (mm)")
    ax.legend()
    axr.axhline(0, color="k", lw=0.8)
    axr.set_xlabel("voltage (V)")
    axr.set_ylabel("residual (mm)")
    fig.savefig(path, dpi=110)
    plt.close(fig)


# --------------------------------------------------------------------------- indentation


#: IR samples before the first press a calibration recording needs for its rest
#: distances (``estimate_baseline_mm``'s minimum; the protocol's 3 s clear give ~300).
REST_SAMPLES_MIN = 5


def _press_samples(path: str, ir_config: IRConfig) -> dict[str, np.ndarray]:
    import numpy as np

    from vision.indentation import (
        IndentationEstimator,
        before_first_contact_mask,
        indentation_at_frames,
    )
    from vision.recording import PadRecording

    rec = PadRecording(path)
    ir, truth = rec.read_ir(), rec.read_truth()
    for name, data in (("ir.csv", ir), ("truth.csv", truth)):
        if data is None:
            raise UserError(f"{rec.path / name}: missing (needed to fit the correction)")
    m = rec.meta
    est = IndentationEstimator.from_config(
        replace(ir_config, correction_coef=()), sensors_mm=m.ir_sensors_mm,
        baseline_mm=m.ir_baseline_mm, base_to_fabric_mm=m.base_to_fabric_mm)
    if est.baseline_mm is None:
        # The rest distances come from the samples before the first press, as in ``fydpad
        # track``; without them every deflection would be off by the mounting's spread.
        rest = before_first_contact_mask(ir[0], truth.t_s, truth.contact)  # type: ignore[index,union-attr]
        if int(rest.sum()) < REST_SAMPLES_MIN:
            raise UserError(
                f"{rec.path / 'ir.csv'}: {int(rest.sum())} IR samples before the first "
                f"press, need {REST_SAMPLES_MIN} for the rest distances: start each "
                "recording with the fabric clear (the protocol's first 3 s) or give "
                "ir.baseline_mm in meta.json")
    r, _ = indentation_at_frames(est, ir[0], ir[1], truth.t_s, truth.contact,  # type: ignore[index]
                                 truth.x_mm, truth.y_mm)  # type: ignore[union-attr]
    c = truth.contact & r.valid & np.isfinite(truth.indentation_mm)  # type: ignore[union-attr]
    # Number the presses (runs of contact) so held-out halves never share one.
    press = np.cumsum(np.diff(np.concatenate([[0], truth.contact.astype(int)])) == 1)  # type: ignore[union-attr]
    return {"plane": r.plane_mm[c], "x": truth.x_mm[c], "y": truth.y_mm[c],  # type: ignore[union-attr]
            "depth": truth.indentation_mm[c], "press": press[c],  # type: ignore[union-attr]
            "e": r.deflection_mm[c],  # type: ignore[index]
            "sensors": np.asarray(m.ir_sensors_mm, np.float64)}


def run_indentation(args: argparse.Namespace) -> int:
    import numpy as np

    from vision.config import IRConfig
    from vision.indentation import SagCorrection, rmse

    if args.protocol:
        from fydpad.indentation_protocol import protocol_text

        print(protocol_text())
        return 0
    if not args.recdirs:
        raise UserError("give the calibration recordings (RECDIR...), or --protocol for how "
                        "to record them")
    config = _load_config(args)
    ir_config: IRConfig = getattr(config, "ir", None) or IRConfig()
    if args.xy_degree < 0 or args.depth_degree < 1:
        raise UserError("--xy-degree must be >= 0 and --depth-degree >= 1")
    parts = [_press_samples(p, ir_config) for p in args.recdirs]
    offset = 0
    for part in parts:  # presses of different recordings are different presses
        part["press"] = part["press"] + offset
        offset = int(part["press"].max(initial=offset)) + 1
    sensors = parts[0].pop("sensors")
    for part in parts[1:]:
        if not np.allclose(part.pop("sensors"), sensors):
            raise UserError("the recordings state different IR sensor positions: calibrate "
                            "one device at a time")
    data = {k: np.concatenate([part[k] for part in parts]) for k in parts[0]}
    need = 3 * SagCorrection.n_coef(args.xy_degree, args.depth_degree)
    n = int(data["depth"].size)
    names = ", ".join(args.recdirs)
    if n < need:
        raise UserError(f"{names}: {n} contact frames with valid IR readings and known depth; "
                        f"the correction needs at least {need}")
    if np.unique(data["press"] % 2).size < 2:
        raise UserError(f"{names}: a single press; record several, at different places")
    try:
        final, held_rmse, scores = SagCorrection.fit_cv(
            data["e"], data["x"], data["y"], data["depth"], data["press"],
            args.xy_degree, args.depth_degree, sensors_mm=sensors)
    except ValueError as exc:
        raise UserError(f"{names}: {exc}") from None
    d = data["depth"]
    summary = [
        f"fydpad calibrate indentation {names} ({date.today().isoformat()})",
        f"{n} contact frames in {len(np.unique(data['press']))} presses, depth "
        f"{d.min():.1f}-{d.max():.1f} mm",
        f"RMSE against the true depth: plane {rmse(data['plane'], d):.2f} mm, corrected "
        f"{held_rmse:.2f} mm (held-out presses; ridge {min(scores, key=scores.get):g})",
    ]
    for line in summary[1:]:
        print(line)
    _write_section(args, "ir", {"correction_coef": final.coef,
                                "correction_per_sensor": True,
                                "correction_xy_degree": final.xy_degree,
                                "correction_depth_degree": final.depth_degree}, summary)
    return 0


# --------------------------------------------------------------------------- force


def run_force(args: argparse.Namespace) -> int:
    import numpy as np

    from fydpad.calibration_examples import write_force_example
    from vision.config import ForceConfig
    from vision.force import ForceCalibrationError, calibrate_force
    from vision.recording import read_csv_columns

    if _example(args, "force", write_force_example):
        return 0
    path = Path(args.data)
    cols = read_csv_columns(path, ("mass_g", "raw"))
    lines = _line_numbers(path)
    m = cols["mass_g"]
    bad = np.flatnonzero((m < 0) | (m > args.full_scale_g))
    if bad.size:
        raise UserError(f"{path}: line {lines[bad[0]]}: mass_g {m[bad[0]]:g} is outside 0-"
                        f"{args.full_scale_g:g} g (the load cell's range)")
    try:
        cal: ForceCalibration = calibrate_force(m, cols["raw"], args.full_scale_g)
    except ForceCalibrationError as exc:
        raise UserError(f"{path}: {exc}") from None
    worst = int(np.argmax(np.abs(cal.residuals_n)))
    summary = [
        f"fydpad calibrate force {path.name} ({date.today().isoformat()})",
        f"{cal.n_points} readings: offset {cal.offset_counts:.1f} counts, gain "
        f"{cal.gain_n_per_count:.6g} N/count, R^2 {cal.r2:.6f}",
        f"residuals: RMS {cal.rms_residual_n * 1000:.2f} mN, worst "
        f"{cal.residuals_n[worst] * 1000:+.2f} mN (line {lines[worst]})",
    ]
    for s in summary[1:]:
        print(s)
    if args.plot:
        _plot_force(args.plot, m, cols["raw"], cal)
    cfg = ForceConfig(cal.offset_counts, cal.gain_n_per_count, args.full_scale_g)
    _write_section(args, "force", {"offset_counts": cfg.offset_counts,
                                   "gain_n_per_count": cfg.gain_n_per_count,
                                   "full_scale_g": cfg.full_scale_g}, summary)
    return 0


def _plot_force(path: str, mass_g: np.ndarray, raw: np.ndarray, cal: ForceCalibration) -> None:
    import numpy as np

    from fydpad.plots import plt
    from vision.config import G_M_S2

    fig, (ax, axr) = plt.subplots(2, 1, figsize=(7, 6), sharex=True, constrained_layout=True)
    ax.plot(raw, mass_g * 1e-3 * G_M_S2, ".", label="known weights")
    g = np.linspace(raw.min(), raw.max(), 2)
    ax.plot(g, cal.gain_n_per_count * (g - cal.offset_counts), "-",
            label=f"fit (R$^2$ {cal.r2:.5f})")
    ax.set_ylabel("force (N)")
    ax.legend()
    axr.plot(raw, cal.residuals_n * 1000, ".")
    axr.axhline(0, color="k", lw=0.8)
    axr.set_xlabel("raw [counts]")
    axr.set_ylabel("residual [mN]")
    fig.savefig(path, dpi=110)
    plt.close(fig)
