"""``fydpad texture``: fit, synthesize, evaluate and identify texture models of every
family, compare the families, the friction staircase and synthetic scans. Parses the
arguments and prints; the work is :mod:`fydpad.texture.operations`'s."""

from __future__ import annotations

# The texture library (SciPy, the families) and the staircase load inside the command
# functions, so that --help starts fast.
import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from fydpad.errors import UserError

if TYPE_CHECKING:  # annotations only
    from fydpad.texture.operations import Synthesis

# What the options list, written out so that --help loads no texture code
# (tests/cli/test_fast_help.py keeps each equal to its source).
#: fydpad.texture.families.KIND_NAMES and FIT_KIND_NAMES
KIND_NAMES = ("lpc", "friction", "grating", "mlp", "penn")
FIT_KIND_NAMES = ("lpc", "friction", "grating", "mlp")


def _floats(text: str) -> list[float]:
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}"
                                         ) from None


def _ratio(text: str) -> tuple[int, int]:
    try:
        v, f = (int(a) for a in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected V:F such as 8:2, got {text!r}") from None
    if not (0 <= v <= 10 and v + f == 10):
        raise argparse.ArgumentTypeError(f"V and F must be 0..10 and add up to 10, got {text!r}")
    return v, f


#: identify's and compare's --seed.
IDENTIFY_SEED_HELP = ("noise seed of the models that synthesize noise (LPC, HaTT; "
                      "default 0): the same seed, the same confusion matrix")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "texture", help="texture models: fit from scans, synthesize, evaluate, identify",
        description=(
            "Speed-indexed LPC texture models (Bianchi 2015, III-B): fit them from texture "
            "scan recordings (docs/texture.md), synthesize eq. 5 at 1 kHz, compare "
            "synthesized with recorded spectra, and identify surfaces from their models. "
            "The other families (--kind): position-indexed friction playback (Jiao 2018), "
            "vibrotactile/friction gratings at a ratio (Ito 2019), the network of Lin 2016 "
            "and Penn HaTT models (Culbertson 2014), behind one contract; 'compare' runs "
            "them on the same scans. "
            "See docs/texture.md and docs/texture_families.md."),
    )
    tsub = p.add_subparsers(dest="texture_command", metavar="SUBCOMMAND", required=True)

    f = tsub.add_parser(
        "fit", help="fit a model file from scans of one surface",
        description=(
            "Fit one texture model file from one or more scans of the same surface. Each "
            "scan's three axes are high-passed at --highpass-hz (hand motion, gravity) and "
            "reduced to one signal by DFT321. Two forms are validated on the scans "
            "themselves: Bianchi 2015's method read plainly (per speed, an LPC of --order "
            "on the samples within --tolerance of it, rendered at the nearest fitted speed) "
            "and the calibrated speed-resolved spectrum; a time block of each speed "
            "plateau and each inner plateau whole are held out in turn, each form is "
            "scored by its log-spectral distance there, the best wins (ties within the "
            "noise to the paper's), is refitted on all the scans and the table printed "
            "(docs/texture.md, 'How fit chooses'). Scans that cannot be validated (fewer "
            "than two plateaus of 4.5 s) get the paper's method. Every model's stability "
            "is checked. The 165-220 Hz band of Bianchi 2015 is stored as the output drive "
            "filter, not used for fitting."),
    )
    f.add_argument("scans", nargs="*", metavar="SCAN.csv", help="texture scan recordings")
    f.add_argument("--out", required=True, metavar="MODEL.json", help="model file to write")
    f.add_argument("--kind", choices=FIT_KIND_NAMES, default="lpc",
                   help="texture family (default lpc). friction: mu(x) = F_f/F_n from scans "
                   "with force_n, friction_n, x_mm (Jiao 2018 IV-B; docs/texture_friction.md)."
                   " grating: a parametric grating at a vibrotactile:friction ratio (Ito 2019 "
                   "4.2; --wavelength-mm, else estimated from the scans; "
                   "docs/texture_grating.md). mlp: the 3-10-1 network of Lin 2016 "
                   "(docs/texture_mlp.md)")
    f.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="a fit option of the family, repeatable (e.g. for mlp: "
                   "--set learning_rate=0.1 --set max_epochs=500; an unknown key is named)")
    f.add_argument("--dx-mm", type=float, default=0.01,
                   help="friction: position grid step (default 0.01 mm)")
    f.add_argument("--lowpass-hz", type=float, default=100.0,
                   help="friction: Jiao 2018's 100 Hz low-pass, applied in position at "
                   "100 Hz / the scans' median speed (cycles/mm)")
    f.add_argument("--wavelength-mm", type=float,
                   help="grating: spatial period (default: estimated from the scans)")
    f.add_argument("--profile", choices=("rect", "sine"), default="rect",
                   help="grating: rectangular (ridge 90 %%, the FYD-pad's R1/R2) or sine")
    f.add_argument("--ratio", metavar="V:F", type=_ratio,
                   help="grating: vibrotactile:friction levels, V+F=10 (default 8:2 for "
                   "lambda >= 1 mm, else 6:4)")
    f.add_argument("--order", type=int, default=200, help="LPC order per speed (default 200)")
    f.add_argument("--speeds", dest="speeds_mm_s", type=_floats,
                   default=[10.0, 20.0, 30.0, 40.0],
                   metavar="S1,S2,..", help="target speeds in mm/s (default 10,20,30,40)")
    f.add_argument("--tolerance", dest="tolerance_mm_s", type=float, default=5.0, metavar="MM_S",
                   help="a run is valid while |speed - target| <= this (default 5 mm/s)")
    f.add_argument("--min-seconds", type=float, default=0.25,
                   help="shortest run used (default 0.25 s)")
    f.add_argument("--highpass-hz", type=float, default=10.0,
                   help="high-pass removing the tool's motion (default 10 Hz)")
    f.add_argument("--form", choices=("auto", "paper", "calibrated"), default="auto",
                   help="auto (default): validate every form on held-out blocks of the "
                   "scans' speed plateaus and whole inner plateaus, keep the best (ties to "
                   "the simpler), refit it on all the scans and print the table; 'paper': "
                   "Bianchi 2015's method read plainly (a 5 mm/s window LPC per speed, no "
                   "interpolation); 'calibrated': the speed-resolved spectrum, the two-"
                   "part S(f,v) times a correction measured at each target speed (needs two "
                   "or more)")
    f.add_argument("--surface", help="surface label (default: the scans' # surface= or name)")
    f.add_argument("--drive-band", dest="drive_band_hz", type=_floats, default=[165.0, 220.0],
                   metavar="LO,HI",
                   help="output drive filter band stored in the model (default 165,220 Hz)")
    f.add_argument("--plot", metavar="FIG.png",
                   help="recorded against model spectra per speed (like Bianchi 2015 "
                   "Fig. 10; lpc fits only)")
    f.set_defaults(func=run_fit)

    s = tsub.add_parser(
        "synth", help="synthesize a model at a speed to t_s,a CSV",
        description=(
            "Render a model of any family for a constant finger speed (after a 0.5 s lead-in "
            "at that speed) and write t_s,a (the vibration, m/s^2) or t_s,<channel>. An "
            "LPC model synthesizes a(k) = e(k) + h^T a(k-1) (eq. 5) at its rate (1 kHz); "
            "below its slowest model the output fades out with speed, above the fastest "
            "it is clamped (with a warning)."),
    )
    s.add_argument("model", metavar="MODEL.json",
                   help="model file from 'fydpad texture fit' (any kind; read from the file), "
                   "or a Penn Haptic Texture Toolkit model, [penn:]FILE.xml (with --force-n)")
    s.add_argument("--speed-mm-s", type=float, required=True, help="finger speed in mm/s")
    s.add_argument("--force-n", type=float,
                   help="normal force in N (needed by models indexed by speed and force: HaTT "
                   "models, penn:FILE.xml or FILE.xml; default 1 N for the others)")
    s.add_argument("--seconds", type=float, required=True, help="duration in seconds")
    s.add_argument("--out", required=True, metavar="OUT.csv|OUT.wav|audio[:DEVICE][@RATE]",
                   help="CSV t_s,a (vibration) or t_s,<channel>; .wav writes a WAV file; "
                   "audio plays it on the sound card (resampled to RATE, default 48000; needs the "
                   "'audio' extra; full scale 1.0, clipped samples counted)")
    s.add_argument("--channel", choices=("vibration", "tension", "audio"),
                   help="output channel (default vibration). vibration/tension: the FYD-pad's "
                   "1 kHz terms; audio: an external display at --audio-hz (friction: "
                   "V = b mu(x) Y(t), 240 Hz carrier; grating: V_e)")
    s.add_argument("--kind", choices=KIND_NAMES,
                   help="check the model file is of this kind (it is read from the file)")
    s.add_argument("--audio-hz", type=float, default=48000.0,
                   help="rate of the audio channel (default 48000)")
    s.add_argument("--x0-mm", type=float,
                   help="position-indexed kinds: start of the stroke (default: the model's)")
    s.add_argument("--drive-filter", action="store_true",
                   help="apply the model's drive band filter (e.g. 165-220 Hz) to the output")
    s.add_argument("--seed", type=int, default=0,
                   help="noise seed of the models that synthesize noise (default 0)")
    s.set_defaults(func=run_synth)

    e = tsub.add_parser(
        "evaluate", help="compare a model's synthesis with a recorded scan",
        description=(
            "Synthesize the model along the scan's own speed trace and compare it with the "
            "scan's DFT321 signal (high-passed, before any drive filter), where the speed is "
            "within the model's range: power-spectrum correlation over 20-500 Hz (Welch, "
            "4 Hz bins; Bianchi 2015's 'correlation in frequency'), log-spectral distance in "
            "dB, band energies, and Bianchi 2015's time correlation (expected near 0: two "
            "realisations of a random process do not correlate sample by sample)."),
    )
    e.add_argument("model", metavar="MODEL.json", help="model file from 'fydpad texture fit'")
    e.add_argument("scan", nargs="+", metavar="SCAN.csv",
                   help="texture scan recording(s) to compare with; with several, their "
                   "figures are averaged too (and, with --second, the targets judged on "
                   "the means: one stroke against one second recording is a draw)")
    e.add_argument("--json", metavar="OUT.json", help="write the figures as JSON")
    e.add_argument("--plot", metavar="FIG.png", help="recorded against synthesized spectra")
    e.add_argument("--seed", type=int, default=0,
                   help="noise seed of an LPC model's synthesis (default 0; the i-th of "
                   "several scans takes SEED + i, a draw of its own)")
    e.add_argument("--second", action="append", metavar="SECOND.csv",
                   help="once per SCAN.csv, in the same order: another recording of the same "
                        "surface at the same speed and about "
                        "as long (a held-out stroke the fit never saw): the ceiling (it "
                        "scored against SCAN.csv as the model is) and whether the model "
                        "meets the targets (correlation >= 0.95, LSD <= the ceiling's "
                        "+ 0.25 dB); no verdict when it is of another surface, speed or "
                        "much shorter")
    e.set_defaults(func=run_evaluate)

    i = tsub.add_parser(
        "identify", help="match scans to models (confusion matrix)",
        description=(
            "An objective analogue of Bianchi 2015 Table I: render every model along each "
            "scan's speed trace and assign the scan to the model with the nearest spectrum "
            "(LPC models: levels in third-octave bands, 20-500 Hz, --distance lsd: 4 Hz bins; "
            "the other families: the spectral shape, --distance shape). A scan's "
            "label is its '# surface=' metadata, else its file name; a model's label is the "
            "surface it was fitted on. Prints the rate; --json writes {rate, labels, "
            "confusion, assignments}."),
    )
    i.add_argument("models", nargs="+", metavar="MODEL.json", help="one model file per surface")
    i.add_argument("--scans", nargs="+", required=True, metavar="SCAN.csv",
                   help="scans to identify (labels from '# surface=' or the file name)")
    i.add_argument("--json", metavar="OUT.json",
                   help="write {rate, labels, confusion, assignments}")
    i.add_argument("--plot", metavar="FIG.png", help="the confusion matrix")
    i.add_argument("--distance", choices=("bands", "lsd", "shape"),
                   help="between the spectra: bands (the LPC family's default: RMS dB "
                   "difference of the third-octave band levels), lsd (log-spectral distance "
                   "on 4 Hz bins) or shape (the other families' default: the dB difference "
                   "without its mean and tilt, as compare)")
    i.add_argument("--seed", type=int, default=0, help=IDENTIFY_SEED_HELP)
    i.set_defaults(func=run_identify)

    c = tsub.add_parser(
        "compare", help="identify the same scans with every family (confusion matrices)",
        description=(
            "Fit one model per surface of each family (--kinds) from the --train scans, "
            "identify every --scans scan with each family (nearest spectral shape of what "
            "the family renders along the scan's own stroke: vibration against the "
            "acceleration; friction: mu against F_f/F_n) and write one confusion matrix "
            "per family. --specimens adds Bianchi 2015's 2 x 2 (SS1..SS4: softness S1/S2 x "
            "roughness R1/R2, Table I): roughness rendered by the family, softness by the "
            "simulated motors and fabric, measured by a simulated indenter press; "
            "identified by spectra alone and by spectra plus stiffness. Needs R1 and R2 "
            "among the scans for --specimens. Writes compare.json and PNG plots to "
            "--out-dir. See docs/texture_families.md."),
    )
    c.add_argument("--train", nargs="+", required=True, metavar="SCAN.csv",
                   help="scans to fit the models on (labels from '# surface=')")
    c.add_argument("--scans", nargs="+", required=True, metavar="SCAN.csv",
                   help="scans to identify (other strokes of the same surfaces)")
    c.add_argument("--kinds", default="lpc,friction,grating,mlp",
                   help="families to compare (default lpc,friction,grating,mlp; one that "
                   "cannot be fitted on the scans is reported, not fatal)")
    c.add_argument("--specimens", action="store_true", help="also the 2 x 2 of Table I")
    c.add_argument("--trials", type=int, default=3, help="--specimens: trials per specimen")
    c.add_argument("--seed", type=int, default=0, help=IDENTIFY_SEED_HELP)
    c.add_argument("--out-dir", required=True, metavar="DIR")
    c.set_defaults(func=run_compare)

    st = tsub.add_parser(
        "staircase", help="set the electrostatic factor b with a user (1-up/1-down)",
        description=(
            "The 1-up/1-down staircase of Jiao 2018 (IV-C): start at b = --start (400), "
            "each trial asks which felt rougher, the real sample (r: b up by --step) or the "
            "virtual one (v: b down); the result is the mean b at the four reversals after "
            "the first two. Answers are read from stdin one per line (pipe them to script "
            "it; q stops), appended to --log as they come (trial,b,answer,reversal), and "
            "an existing log is replayed first, so a stopped staircase resumes. With --model "
            "(a friction model) the result is written into it as electrostatic.b_v."),
    )
    st.add_argument("--log", required=True, metavar="LOG.csv", help="answers log (resumable)")
    st.add_argument("--start", type=float, default=400.0, help="first b (default 400)")
    st.add_argument("--step", type=float, default=10.0, help="step of b (default 10)")
    st.add_argument("--model", metavar="FRICTION.json",
                    help="write the result into this friction model's electrostatic.b_v")
    st.set_defaults(func=run_staircase)

    g = tsub.add_parser(
        "generate-scans", help="write synthetic scans (a physical generator, not AR)",
        description=(
            "Write synthetic texture scans: a tool dragged by a hand over a surface profile "
            "with impacts, stick-slip, a tool resonance, sensor noise, hand motion and "
            "gravity. Includes Bianchi 2015's gratings R1 (3.90 mm) and R2 (2.15 mm). Files are "
            "named SURFACE_SPEEDmms_sSEED.csv. Deterministic per seed."),
    )
    g.add_argument("--out-dir", metavar="DIR", help="folder to write to (created; needed "
                   "unless --list)")
    g.add_argument("--textures", default="all",
                   help="comma-separated names or 'all' (--list shows them)")
    g.add_argument("--speeds", type=_floats, default=[10.0, 20.0, 30.0, 40.0], metavar="S,..")
    g.add_argument("--strokes", type=int, default=2, help="strokes per texture and speed")
    g.add_argument("--seconds", type=float, default=8.0, help="stroke length (default 8 s)")
    g.add_argument("--seed", type=int, default=1, help="first stroke seed (default 1)")
    g.add_argument("--list", action="store_true", help="list the textures and exit")
    g.add_argument("--friction", action="store_true",
                   help="also force_n and friction_n columns (a Coulomb/stick-slip contact "
                   "over the same profile with a varying normal load)")
    g.add_argument("--load-scale", type=float, default=1.0, metavar="S",
                   help="the hand's mean load over each texture's own (default 1). Below 1 "
                   "the tip leaves the surface more often and lands with impacts: at 0.3, "
                   "a light touch, brick from 20 mm/s, the sandpapers from 25-30 mm/s, cork "
                   "barely "
                   "(docs/texture.md, 'The scan generator'); written as # load_scale=S")
    g.set_defaults(func=run_generate)


def _check_out(path: str | None, option: str) -> None:
    """An output file's folder must exist and the path not be a folder: a one-line error
    before the work (a fit takes minutes), not a traceback after it."""
    if path is None:
        return
    out = Path(path)
    if out.is_dir():
        raise UserError(f"{option} {path}: is a directory, expected a file name")
    folder = out.parent
    if not folder.is_dir():
        raise UserError(f"{option} {path}: directory {folder} does not exist "
                        f"(mkdir -p {folder})")


def _make_dir(path: str, option: str) -> Path:
    """``--out-dir``: created with its parents; a path that cannot be is one line."""
    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"{option} {path}: cannot be created ({exc.strerror})") from None
    return out


def _warn(command: str, messages: list[str], where: str = "") -> None:
    """Warnings as one line each: ``fydpad texture CMD: warning: [WHERE: ]MESSAGE``."""
    for msg in messages:
        print(f"fydpad texture {command}: warning: {where + ': ' if where else ''}{msg}",
              file=sys.stderr)


def _scan_names(paths: list[str]) -> str:
    """The scans a warning is about, shortened past three."""
    return ", ".join(paths) if len(paths) <= 3 else (
        f"{paths[0]}, {paths[1]} and {len(paths) - 2} more scans")


def _set_options(pairs: list[str]) -> dict:
    """``--set KEY=VALUE`` strings -> options (int, float, true/false or text)."""
    out: dict = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        if not sep or not key.strip():
            raise UserError(f"--set: expected KEY=VALUE, got {pair!r}")
        value: object = text
        for conv in (int, float):
            try:
                value = conv(text)
                break
            except ValueError:
                pass
        if text.lower() in ("true", "false"):
            value = text.lower() == "true"
        out[key.strip()] = value
    return out


def _write_json(path: str, data: dict) -> None:
    """Strict JSON: a figure that is not a number (NaN) is written as null."""
    from vision.strict_json import finite  # NumPy: not for --help

    Path(path).write_text(json.dumps(finite(data), indent=1, allow_nan=False) + "\n",
                          encoding="utf-8")


def run_fit(args: argparse.Namespace) -> int:
    from fydpad.progress import progress
    from fydpad.texture import operations as ops

    _check_out(args.out, "--out")
    _check_out(args.plot, "--plot")
    options = {**vars(args),
               "wrap_iterations": lambda it: progress(it, desc="spectral model", unit="it")}
    fitted = ops.fit_model(args.kind, args.scans, options, args.out, args.plot,
                           extra=_set_options(args.set))
    _warn("fit", fitted.notes)
    _warn("fit", fitted.warnings, _scan_names(args.scans))
    for line in fitted.lines:
        print(line)
    return 0


def run_synth(args: argparse.Namespace) -> int:
    from fydpad.texture import operations as ops
    from fydpad.texture.lpc.coverage import describe

    if not _is_audio(args.out):
        _check_out(args.out, "--out")
    syn = ops.synthesize(args.model, speed_mm_s=args.speed_mm_s, seconds=args.seconds,
                         channel=args.channel, force_n=args.force_n, audio_hz=args.audio_hz,
                         x0_mm=args.x0_mm, kind=args.kind,
                         drive_filter=args.drive_filter, seed=args.seed)
    _warn("synth", syn.warnings, args.model)
    if syn.unscanned:
        print(f"fydpad texture synth: note: {args.model}: no scan went at "
              f"{args.speed_mm_s:g} mm/s (none between {describe(syn.unscanned)}): the "
              "spectrum is the model's interpolation there (docs/texture.md, 'Speed "
              "coverage')", file=sys.stderr)
    if _is_audio(args.out):
        _play_audio(args.out, syn)
    else:
        ops.write_synthesis(args.out, syn, args.speed_mm_s)
    print(f"{args.out}: {syn.family.kind} {syn.channel}, {syn.y.size} samples at "
          f"{syn.rate_hz:g} Hz, rms {syn.rms:.4g}")
    return 0


def _is_audio(out: str) -> bool:
    return out == "audio" or out.startswith(("audio:", "audio@"))


def _play_audio(spec: str, syn: Synthesis) -> None:
    """Play on the sound card through the audio channel (waits for the end)."""
    from fydpad.channels import ChannelError, open_channel
    from fydpad.channels.audio import AudioChannel

    try:
        ch = open_channel(spec, syn.rate_hz, syn.channel)
        assert isinstance(ch, AudioChannel)
        with ch:
            ch.play(syn.y)
    except ChannelError as exc:
        raise UserError(str(exc)) from None
    st = ch.stats
    print(f"{spec}: played {st['played_frames']} frames at {ch.device_rate_hz:g} Hz on "
          f"{ch.device_name}; {st['underruns']} underruns, {st['clipped_frames']} clipped, "
          f"{st['dropped_frames']} dropped")


def run_evaluate(args: argparse.Namespace) -> int:
    from fydpad.texture import operations as ops

    _check_out(args.json, "--json")
    _check_out(args.plot, "--plot")
    results = ops.evaluate_model(args.model, args.scan, args.second, seed=args.seed)
    for path, r in zip(args.scan, results, strict=True):
        if len(args.scan) > 1:
            print(f"{path}:")
        for line in r.lines:
            print(line)
        _warn("evaluate", r.warnings)
    if len(results) == 1:
        out = results[0].out
    else:
        out, lines = ops.over_scans(args.model, results)
        for line in lines:
            print(line)
    if args.json:
        _write_json(args.json, out)
    if args.plot:
        ops.plot_evaluation(args.plot, results)
    return 0


def run_identify(args: argparse.Namespace) -> int:
    from fydpad.progress import progress
    from fydpad.texture import operations as ops
    from fydpad.texture.plots import plot_confusion

    _check_out(args.json, "--json")
    _check_out(args.plot, "--plot")
    kind, ident = ops.identify_models(
        args.models, args.scans, distance=args.distance, seed=args.seed,
        wrap=lambda it: progress(it, total=len(args.scans), desc="identify"))
    print(f"{kind}: identification rate {ident.rate:.1%} ({len(args.scans)} scans, "
          f"{len(args.models)} models)")
    if args.json:
        _write_json(args.json, {"kind": kind, **ident.to_json()})
    if args.plot:
        plot_confusion(args.plot, ident, f"{kind}: rate {ident.rate:.0%}")
    return 0


def run_compare(args: argparse.Namespace) -> int:
    from fydpad.texture import operations as ops
    from fydpad.texture.scan_io import read_scans

    kinds = [k.strip() for k in args.kinds.split(",") if k.strip()]
    out_dir = _make_dir(args.out_dir, "--out-dir")
    train, test = read_scans(args.train), read_scans(args.scans)
    if args.specimens:  # the pad's softness too: outside fydpad.texture
        from fydpad.specimen_experiment import check_specimen_scans, specimens_command

        by_surface = check_specimen_scans(train, test)
    result, lines, fitted = ops.compare_command(train, test, kinds, out_dir, args.seed)
    if args.specimens:
        result["specimens"], more = specimens_command(fitted, by_surface, out_dir, args.trials)
        lines += more
    for line in lines:
        print(line)
    _write_json(str(out_dir / "compare.json"), result)
    print(f"{out_dir}: compare.json and confusion plots")
    return 0


def run_staircase(args: argparse.Namespace) -> int:
    from fydpad.texture.families.friction import set_electrostatic_b
    from fydpad.web.experiment import ExperimentError
    from fydpad.web.staircase import StaircaseSession

    _check_out(args.log, "--log")
    try:
        session = StaircaseSession.from_log(args.log, args.start, args.step)
    except ExperimentError as exc:
        raise UserError(str(exc)) from None
    stairs = session.stairs
    if stairs.trials:
        print(f"{args.log}: resumed after {stairs.trials} trials, "
              f"{len(stairs.reversals)} reversals")
    while not stairs.done:
        print(f"trial {stairs.trials + 1}: b = {stairs.b:g}. Which felt rougher, the real "
              "or the virtual sample? [r/v, q to stop] ", end="", flush=True)
        line = sys.stdin.readline()
        if not sys.stdin.isatty():  # piped answers: echo them, so the log reads well
            print(line.strip())
        if not line or line.strip().lower() in ("q", "quit"):
            print(f"\nstopped after {stairs.trials} trials; run again to resume")
            return 0
        try:
            session.answer(line)  # logged (fsync'ed) as it comes: a crash loses nothing
        except ExperimentError:
            print("please answer r (real rougher) or v (virtual rougher)")
    used = stairs.reversals[stairs.skip_reversals:stairs.skip_reversals + stairs.use_reversals]
    print(f"b = {stairs.result:g} (mean of reversals {', '.join(f'{v:g}' for v in used)}; "
          f"{stairs.trials} trials)")
    if args.model:
        set_electrostatic_b(args.model, stairs.result)
        print(f"{args.model}: electrostatic.b_v = {stairs.result:g}")
    return 0


def run_generate(args: argparse.Namespace) -> int:
    from fydpad.progress import progress
    from fydpad.synth.texture_scans import TEXTURES, write_scans

    if args.list:
        for t in TEXTURES.values():
            print(f"{t.name:16s} period {t.period_mm:g} mm, resonance {t.resonance_hz:g} Hz")
        return 0
    if args.out_dir is None:
        raise UserError("generate-scans: give --out-dir DIR (or --list to see the textures)")
    out = _make_dir(args.out_dir, "--out-dir")
    n = write_scans(out, args.textures, args.speeds, args.strokes, args.seconds, args.seed,
                    args.friction, args.load_scale,
                    wrap=lambda it: progress(it, total=len(it), desc="generate"))
    print(f"{out}: {n} scans")
    return 0
