"""``fydpad softness``: characterise the fabric (k(theta) table) and specimens (lambda).

Layouts of the input CSVs and of the table: ``docs/softness.md``.
"""

from __future__ import annotations

# Libraries are imported inside the command functions, so that --help starts fast.
import argparse
import sys
import warnings
from pathlib import Path

from fydpad.errors import UserError
from fydpad.softness import (
    PAPER_RANGE_N_PER_MM,
    SPECIMENS,
    SoftnessConfig,
    SoftnessError,
    SoftnessTable,
    SoftnessWarning,
    characterise_fabric,
    fit_specimen,
    save_table,
)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "softness",
        help="characterise the fabric's stiffness table and specimens",
        description=(
            "Fit the fabric's stiffness k(theta) per motor position from indenter data "
            "(F = k * delta, paper Fig. 6) into the table the station inverts to render a "
            "stiffness, or fit a specimen's lambda (F = lambda * delta, paper IV-A)."
        ),
    )
    ss = p.add_subparsers(dest="softness_command", metavar="ACTION", required=True)
    c = ss.add_parser(
        "calibrate", help="fit k(theta) from indenter data and write the softness table",
        description=(
            "DATA.csv: theta_rad (or theta_deg),indentation_mm,force_n, one row per "
            "indenter sample, several motor positions. Writes the table CSV "
            "(theta_rad,k_n_per_mm,r2,n_samples). Fits with R^2 below 0.932 (the paper's "
            "lowest) or a k(theta) that is not monotonic are warned about; with --strict "
            "they are errors and no table is written."
        ),
    )
    c.add_argument("data", metavar="DATA.csv", nargs="?",
                   help="indenter samples at several theta")
    c.add_argument("--out", metavar="TABLE", help="softness table CSV to write")
    c.add_argument("--example", metavar="DIR",
                   help="write sample indenter data of the simulated fabric "
                        "(DIR/softness_indenter.csv) to try the command on, and exit")
    c.add_argument("--plot", metavar="PNG", help="draw the data and fitted lines (Fig. 6)")
    c.add_argument("--strict", action="store_true",
                   help="refuse a table with a poor fit or a non-monotonic k(theta)")
    c.set_defaults(func=run_calibrate)
    s = ss.add_parser(
        "fit-specimen", help="fit a specimen's stiffness lambda from indenter data",
        description=(
            "DATA.csv: indentation_mm,force_n. Prints lambda of F = lambda * delta with "
            f"its R^2 (the paper: > 0.924) and the nearest of the paper's specimens "
            f"({', '.join(f'{k} {v.lambda_n_per_mm} N/mm' for k, v in SPECIMENS.items())})."
        ),
    )
    s.add_argument("data", metavar="DATA.csv", nargs="?",
                   help="indenter samples on one specimen")
    s.add_argument("--example", metavar="DIR",
                   help="write sample indenter data of two specimens (the paper's S1 and S2 "
                        "lambdas: DIR/specimen_S1.csv, DIR/specimen_S2.csv), and exit")
    s.add_argument("--name", help="specimen name (default: the file's stem)")
    s.add_argument("--plot", metavar="PNG", help="draw the data and the fitted line")
    s.set_defaults(func=run_fit_specimen)


def _read(path: str, required: tuple[str, ...], optional: tuple[str, ...] = ()) -> dict:
    from vision.recording import RecordingError, read_csv_columns

    try:
        return read_csv_columns(path, required, optional)
    except RecordingError as exc:
        raise UserError(str(exc)) from None


def _fit_quietly(fn, *args, **kwargs):
    """Run a fit, collecting its SoftnessWarnings (they are printed as one line each)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", SoftnessWarning)
        result = fn(*args, **kwargs)
    return result, [str(w.message) for w in caught if issubclass(w.category, SoftnessWarning)]


def run_calibrate(args: argparse.Namespace) -> int:
    import numpy as np

    if args.example:
        from fydpad.calibration_examples import write_softness_example

        path = write_softness_example(Path(args.example))
        print(f"wrote {path}: fit it with `fydpad softness calibrate {path} --out "
              "softness_table.csv`")
        return 0
    if args.data is None or args.out is None:
        raise UserError("softness calibrate: give DATA.csv and --out TABLE (or --example DIR "
                        "for sample data)")
    cols = _read(args.data, ("indentation_mm", "force_n"), ("theta_rad", "theta_deg"))
    if "theta_rad" in cols:
        theta = cols["theta_rad"]
    elif "theta_deg" in cols:
        theta = np.deg2rad(cols["theta_deg"])
    else:
        raise UserError(f"{args.data}: missing column theta_rad (or theta_deg)")
    try:
        table, notes = _fit_quietly(characterise_fabric, theta, cols["indentation_mm"],
                                    cols["force_n"], SoftnessConfig())
    except SoftnessError as exc:
        raise UserError(f"{args.data}: {exc}") from None
    if args.strict and notes:
        raise UserError(f"{args.data}: {notes[0]} (--strict: no table written)")
    for n in notes:
        print(f"warning: {n}", file=sys.stderr)
    out = save_table(table, args.out, source=Path(args.data).name)
    lo, hi = table.k_range_n_per_mm
    for t, k, r2, n in zip(table.theta_rad, table.k_n_per_mm, table.r2, table.n_samples,
                           strict=True):
        print(f"theta = {t:.3f} rad: k = {k:.3f} N/mm, R^2 = {r2:.3f} ({n} samples)")
    print(f"range {lo:.3f}-{hi:.3f} N/mm (paper: {PAPER_RANGE_N_PER_MM[0]}-"
          f"{PAPER_RANGE_N_PER_MM[1]} N/mm); table written to {out}")
    if args.plot:
        plot_fabric(args.plot, theta, cols["indentation_mm"], cols["force_n"], table)
        print(f"plot written to {args.plot}")
    return 0


def run_fit_specimen(args: argparse.Namespace) -> int:
    if args.example:
        from fydpad.calibration_examples import write_specimen_example

        path = write_specimen_example(Path(args.example))
        print(f"wrote {path} and {path.with_name('specimen_S2.csv')}: fit each with "
              f"`fydpad softness fit-specimen {path}`")
        return 0
    if args.data is None:
        raise UserError("softness fit-specimen: give DATA.csv (or --example DIR for sample "
                        "data)")
    cols = _read(args.data, ("indentation_mm", "force_n"))
    name = args.name or Path(args.data).stem
    try:
        (spec, fit, notes), _ = _fit_quietly(
            fit_specimen, cols["indentation_mm"], cols["force_n"], name, SoftnessConfig())
    except SoftnessError as exc:
        raise UserError(f"{args.data}: {exc}") from None
    for n in notes:
        print(f"warning: {n}", file=sys.stderr)
    nearest = min(SPECIMENS.values(), key=lambda s: abs(s.lambda_n_per_mm - spec.lambda_n_per_mm))
    print(f"{name}: lambda = {fit.k_n_per_mm:.3f} N/mm, R^2 = {fit.r2:.3f} ({fit.n} samples); "
          f"nearest paper specimen {nearest.name} ({nearest.lambda_n_per_mm} N/mm)")
    if args.plot:
        plot_specimen(args.plot, cols["indentation_mm"], cols["force_n"], name,
                      fit.k_n_per_mm, fit.r2)
        print(f"plot written to {args.plot}")
    return 0


# ---------------------------------------------------------------------- plots


def plot_fabric(path: str | Path, theta_rad, indentation_mm, force_n,
                table: SoftnessTable) -> Path:
    """Force-indentation data per motor position with the fitted lines (paper Fig. 6),
    and k(theta) with the monotonic curve the station inverts."""
    import numpy as np

    from fydpad.plots import plt

    th = np.round(np.asarray(theta_rad, float), 6)
    d = np.asarray(indentation_mm, float)
    f = np.asarray(force_n, float)
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 4.8), constrained_layout=True,
                                 gridspec_kw={"width_ratios": (1.5, 1)})
    cmap = plt.get_cmap("viridis")
    dmax = float(np.nanmax(d)) if d.size else 1.0
    for i, (t, k, r2) in enumerate(zip(table.theta_rad, table.k_n_per_mm, table.r2,
                                       strict=True)):
        color = cmap(i / max(len(table.theta_rad) - 1, 1))
        sel = th == np.round(t, 6)
        ax.scatter(d[sel], f[sel], s=8, color=color, alpha=0.6)
        ax.plot([0, dmax], [0, k * dmax], color=color, lw=1.8,
                label=f"θ = {t:.2f} rad: k = {k:.3f} N/mm, R² = {r2:.3f}")
    ax.set_xlabel("indentation δ (mm)")
    ax.set_ylabel("force F (N)")
    ax.set_title("force-indentation at each motor position (F = k δ)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    bx.axhspan(*PAPER_RANGE_N_PER_MM, color="0.9", label="paper's range")
    bx.plot(table.theta_rad, table.k_n_per_mm, "o", color="C0", label="fitted k(θ)")
    bx.plot(table.theta_rad, table.monotonic_k, "-", color="C1", label="inverted (monotonic)")
    bx.set_xlabel("motor position θ [rad]")
    bx.set_ylabel("stiffness k [N/mm]")
    bx.set_title("softness table")
    bx.grid(alpha=0.3)
    bx.legend(fontsize=8)
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_specimen(path: str | Path, indentation_mm, force_n, name: str,
                  lambda_n_per_mm: float, r2: float) -> Path:
    """A specimen's data, its fitted line and the paper's two softness levels."""
    import numpy as np

    from fydpad.plots import plt

    d = np.asarray(indentation_mm, float)
    f = np.asarray(force_n, float)
    dmax = float(np.nanmax(d)) if d.size else 1.0
    fig, ax = plt.subplots(figsize=(7, 4.8), constrained_layout=True)
    ax.scatter(d, f, s=8, color="C0", alpha=0.6, label=f"{name} data")
    ax.plot([0, dmax], [0, lambda_n_per_mm * dmax], color="C1", lw=2,
            label=f"fit: λ = {lambda_n_per_mm:.3f} N/mm, R² = {r2:.3f}")
    for level, style in ((0.88, "--"), (0.39, ":")):
        ax.plot([0, dmax], [0, level * dmax], style, color="0.5", lw=1,
                label=f"paper: {level} N/mm")
    ax.set_xlabel("indentation δ (mm)")
    ax.set_ylabel("force F (N)")
    ax.set_title(f"specimen {name}: F = λ δ")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
