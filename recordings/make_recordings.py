"""Regenerate the bundled synthetic recordings: ``python recordings/make_recordings.py``.

Each recording is ``fydpad synth`` with a fixed seed (below), so it is reproducible on
any machine with the same library versions. Video: ``video.mp4`` (mp4v), because the
whole of ``recordings/`` has to stay under 12 MB and mp4v is several times smaller
than MJPG on this footage. The webcam's own MJPG round trip is turned off for them:
mp4v is itself an 8x8-DCT codec with 4:2:0 chroma, so it leaves the same kind of block
and chroma artefacts on the frames, and a JPEG round trip before it doubles the size
(its blocking costs mp4v bits) without making the footage any harder. The sensor noise
is slightly lower than ``fydpad synth``'s default for the same reason (size); the
decoded frames still differ from a noise-free render by ~3.3 grey levels RMS.

``--calibration`` (a separate step: it leaves the recordings as they are) writes
``device.toml``, the synthetic device's calibration as a lab would make it once: the
indentation correction beyond the plane (docs/indentation.md), fitted by ``fydpad
calibrate indentation`` on its own sessions of taps (``CALIBRATION_SEEDS``, none of them
a bundled recording's), rendered to a temporary directory and not kept. ``fydpad demo``
loads it as its device configuration.

Pass ``--check`` to print, for each recording, the paper tracker's and the robust
tracker's errors against ``truth.csv`` and the plane indentation's RMSE.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
from dataclasses import replace
from pathlib import Path

from fydpad.synth import Effects, SynthConfig, SyntheticPad

HERE = Path(__file__).resolve().parent

_BUNDLED = SynthConfig(mjpg_quality=None, read_noise=0.8, shot_gain=0.01)

#: name -> configuration (trajectory, duration, seed, effects).
RECORDINGS: dict[str, SynthConfig] = {
    "circle": replace(_BUNDLED, trajectory="circle", seconds=10.0, seed=11),
    "lissajous": replace(_BUNDLED, trajectory="lissajous", seconds=10.0, seed=12),
    "tapping": replace(_BUNDLED, trajectory="tapping", seconds=10.0, seed=17),
    # Several real-footage conditions at once: uneven light, room light dips and
    # flicker, auto-exposure, daylight gradient, stains, the hand's shadow, fast strokes.
    "hard": replace(_BUNDLED, trajectory="walk", seconds=4.5, seed=14,
                    effects=Effects(uneven_light=True, room_light=True, auto_exposure=True,
                                    daylight=True, stains=True, hand_shadow=True,
                                    fast=True)),
}


#: The calibration sessions: taps at random places 10-50 mm deep, 60 s each at 10 fps
#: (about 150 presses in all; the corners need many to be covered, docs/indentation.md).
CALIBRATION_SEEDS = tuple(range(101, 109))
CALIBRATION = replace(SynthConfig(), trajectory="tapping", seconds=60.0, fps=10.0)
CALIBRATION_FILE = HERE / "device.toml"


def make_calibration() -> None:
    from fydpad.cli import main as fydpad_main
    from fydpad.config import load_config

    with tempfile.TemporaryDirectory() as tmp:
        dirs = []
        for seed in CALIBRATION_SEEDS:
            out = Path(tmp) / f"taps-{seed}"
            SyntheticPad(replace(CALIBRATION, seed=seed)).write(out)
            dirs.append(str(out))
        fitted = Path(tmp) / "fitted.toml"
        if fydpad_main(["calibrate", "indentation", *dirs, "--out", str(fitted)]) != 0:
            raise SystemExit("fydpad calibrate indentation failed")
        ir = load_config(fitted).ir
        notes = [line.replace(tmp + "/", "") for line in fitted.read_text().splitlines()
                 if line.startswith("#")]
    seeds = f"{CALIBRATION_SEEDS[0]}-{CALIBRATION_SEEDS[-1]}"
    lines = [
        "# The bundled recordings' synthetic device, calibrated once as a lab would: the",
        "# indentation correction beyond the plane fitted on its own tapping sessions",
        f"# (seeds {seeds}, not the bundled recordings): python recordings/make_recordings.py"
        " --calibration",
        *notes,
        "[ir]",
        "correction_coef = [" + ", ".join(repr(float(c)) for c in ir.correction_coef) + "]",
        "correction_per_sensor = true",
        f"correction_xy_degree = {ir.correction_xy_degree}",
        f"correction_depth_degree = {ir.correction_depth_degree}",
        "",
    ]
    CALIBRATION_FILE.write_text("\n".join(lines), encoding="utf-8")
    print(f"written {CALIBRATION_FILE}")


def make(names: list[str]) -> None:
    for name in names:
        out = HERE / name
        if out.exists():
            shutil.rmtree(out)
        SyntheticPad(RECORDINGS[name]).write(out, video_name="video.mp4")
        size = sum(p.stat().st_size for p in out.iterdir())
        print(f"{name}: {size / 1e6:.2f} MB")
    total = sum(p.stat().st_size for p in HERE.rglob("*") if p.is_file())
    print(f"recordings/ in all: {total / 1e6:.2f} MB")


def check(names: list[str]) -> None:
    from fydpad.synth.check import check_recording

    for name in names:
        for method in ("paper", "robust"):
            r = check_recording(HERE / name, method)
            t = r.tracking
            print(f"{name:10s} {method:6s}: RMSE {t.rmse_mm:.3f} mm (max {t.max_error_mm:.2f}), "
                  f"missed {t.missed}, false {t.false} of {t.contact_frames} contact frames; "
                  f"plane indentation RMSE {r.plane_rmse_mm:.2f} mm "
                  f"(depths up to {r.max_indentation_mm:.0f} mm)")
            s = r.steady
            print(f"{'':10s} {'':6s}  steady frames (not next to a touch or release): "
                  f"RMSE {s.rmse_mm:.3f} mm, missed {s.missed}, false {s.false}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", default=list(RECORDINGS), help="recordings to make")
    ap.add_argument("--check", action="store_true", help="score them against their truth")
    ap.add_argument("--no-make", action="store_true", help="only check the existing ones")
    ap.add_argument("--calibration", action="store_true",
                    help="only (re)write device.toml, the device's indentation calibration")
    args = ap.parse_args()
    if args.calibration:
        make_calibration()
        return
    if not args.no_make:
        make(args.names)
    if args.check:
        check(args.names)


if __name__ == "__main__":
    main()
