"""MAE per axis on the bundled recordings: the UR5e in MuJoCo through the real UR slave
code (``--ur-host sim``) next to the PyBullet iiwa, each beside the paper's condition
(10 Hz master, slave holds), in one run. ``--sweep`` measures servoL lookahead x gain on
one recording (main pass only).

    python benchmarks/bench_ur_sim.py                 # the table of docs/teleop.md
    python benchmarks/bench_ur_sim.py --sweep circle  # the lookahead/gain sweep
"""

from __future__ import annotations

import argparse
import copy
import logging

from fydpad.bundled import bundled_recording
from fydpad.commands.demo import demo_config_path
from fydpad.config import load_config
from fydpad.teleop_run import recording_states, truth_rows
from teleop.master import run_local_sim
from vision.recording import PadRecording

RECORDINGS = ("circle", "hard", "lissajous", "tapping")


def axes(d: dict) -> str:
    return " / ".join(f"{d[a]:5.2f}" for a in ("x", "y", "z"))


def arm_config(base, robot: str, lookahead_s: float | None = None, gain: float | None = None):
    cfg = copy.deepcopy(base)
    cfg.slave.robot = robot
    if robot == "ur":
        cfg.slave.ur_host = "sim"
        if lookahead_s is not None:
            cfg.slave.ur_lookahead_s = lookahead_s
        if gain is not None:
            cfg.slave.ur_gain = gain
    return cfg


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--recordings", nargs="+", default=list(RECORDINGS))
    ap.add_argument("--sweep", metavar="NAME", help="lookahead x gain sweep on this recording")
    args = ap.parse_args()
    logging.getLogger("teleop").setLevel(logging.ERROR)
    config = load_config(demo_config_path(None))
    base = config.teleop
    if args.sweep:
        rec = PadRecording(bundled_recording(args.sweep))
        states = recording_states(rec, config)
        print(f"{args.sweep}: UR5e in MuJoCo, MAE x / y / z mm (main pass)")
        for lookahead in (0.03, 0.05, 0.1, 0.2):
            for gain in (300.0, 600.0, 2000.0):
                s = run_local_sim(states, arm_config(base, "ur", lookahead, gain),
                                  truth=truth_rows(rec), baseline=False)
                print(f"  lookahead {lookahead:4.2f} s gain {gain:6.0f}: "
                      f"{axes(s.report['mae_mm'])}  lag {s.report['lag_ms']:5.1f} ms",
                      flush=True)
        return
    print("MAE x / y / z mm; paper's condition = 10 Hz master, slave holds each sample; "
          f"UR servoL lookahead {base.slave.ur_lookahead_s} s")
    for name in args.recordings:
        rec = PadRecording(bundled_recording(name))
        states = recording_states(rec, config)
        ur_default = f"MuJoCo UR5e gain {base.slave.ur_gain:.0f}"
        for label, robot, gain in (("PyBullet iiwa       ", "sim", None),
                                   (ur_default, "ur", None),
                                   ("MuJoCo UR5e gain 2000", "ur", 2000.0)):
            s = run_local_sim(states, arm_config(base, robot, gain=gain), truth=truth_rows(rec))
            r = s.report
            print(f"{name:9s} {label}: {axes(r['mae_mm'])}   paper's condition "
                  f"{axes(r['baseline_mae_mm'])}   vs true finger {axes(r['truth_mae_mm'])}",
                  flush=True)


if __name__ == "__main__":
    main()
