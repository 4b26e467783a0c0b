"""`teleop` command: run a slave, generate CurveZMQ keys.

The slave's libraries (ZeroMQ, PyBullet, NumPy) are imported inside the commands, so
that `teleop --help` loads none of them."""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import signal
import sys
import threading
import tomllib
from pathlib import Path

from teleop.config import OTHER_SECTIONS, TeleopConfig, check_rt_priority
from vision.errors import FydpadError
from vision.strict_json import finite

log = logging.getLogger("teleop")


def load_config(path: str | None) -> TeleopConfig:
    """TeleopConfig from a TOML file: the device file of `fydpad config show` (tables
    [teleop.link] [teleop.safety] [teleop.mapping] [teleop.prediction] [teleop.slave], the
    other packages' sections skipped by name) or a file of its own with those tables at the
    top level. An unknown section or key is refused by name."""
    cfg = TeleopConfig()
    if path is None:
        return cfg
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise SystemExit(f"teleop: cannot read config {path}: {e}") from e
    prefix = ""
    if "teleop" in data:
        for section in data:
            if section not in OTHER_SECTIONS and section != "teleop":
                raise SystemExit(f"teleop: {path}: unknown section [{section}]")
        data, prefix = data["teleop"], "teleop."
    else:
        data = {k: v for k, v in data.items() if k not in OTHER_SECTIONS}
    for section, value in data.items():
        if not hasattr(cfg, section) or not isinstance(value, dict):
            if section == "baseline_rate_hz":
                cfg.baseline_rate_hz = float(value)
                continue
            raise SystemExit(f"teleop: {path}: unknown section [{prefix}{section}]")
        sub = getattr(cfg, section)
        names = {f.name: f for f in dataclasses.fields(sub)}
        for k, v in value.items():
            if k not in names:
                raise SystemExit(f"teleop: {path}: unknown key {prefix}{section}.{k} "
                                 f"(known: {', '.join(names)})")
            setattr(sub, k, tuple(v) if isinstance(v, list) else v)
    try:
        check_rt_priority(cfg.link.rt_priority)
    except ValueError as e:
        raise SystemExit(f"teleop: {path}: {e}") from None
    return cfg


def _cmd_slave(args: argparse.Namespace) -> int:
    from teleop.realtime import realtime_scheduling  # command module: fast --help

    cfg = load_config(args.config)
    cfg.slave.robot = args.robot
    if args.ur_host:
        cfg.slave.ur_host = args.ur_host
    if args.curve:
        cfg.link.curve = args.curve
    if args.keys:
        cfg.link.keys_dir = args.keys
    if args.rt_priority is not None:
        if not 0 <= args.rt_priority <= 99:
            print("teleop slave: --rt-priority: real-time priority must be 0 (off) or 1-99, "
                  f"got {args.rt_priority}", file=sys.stderr)
            return 2
        cfg.link.rt_priority = args.rt_priority
    # Before NumPy's thread pool, the socket and the arm start their threads (imported in
    # _run_slave for that reason): threads inherit the policy, earlier ones keep theirs.
    with realtime_scheduling(cfg.link.rt_priority) as scheduling:
        return _run_slave(args, cfg, scheduling)


def _run_slave(args: argparse.Namespace, cfg: TeleopConfig, scheduling: str) -> int:
    # Imported after the scheduling policy is set (see _cmd_slave), and not for --help.
    from teleop.link import SlaveSocket
    from teleop.mapping import Mapping
    from teleop.slave import SlaveLoop, make_arm

    stop = threading.Event()

    def on_signal(signum: int, _frame: object) -> None:
        log.info("signal %d: stopping the robot", signum)
        stop.set()

    old_handlers = (signal.signal(signal.SIGTERM, on_signal),
                    signal.signal(signal.SIGINT, on_signal))
    arm = make_arm(cfg)
    try:
        with SlaveSocket(args.bind, cfg.link) as sock:
            arm.start(Mapping(cfg.mapping).to_robot([0.0, 0.0, 0.0]))
            loop = SlaveLoop(arm, sock, cfg)
            print(f"teleop slave ({args.robot}) listening on {sock.endpoint}"
                  f"{' (CurveZMQ)' if sock.curve else ''} [scheduling: {scheduling}]", flush=True)
            try:
                loop.run(stop, duration_s=args.duration)
            finally:
                arm.close()
                rep = loop.report()
                rep["scheduling"] = scheduling
                if args.report:
                    Path(args.report).write_text(
                        json.dumps(finite(rep), indent=2, allow_nan=False) + "\n")
                print(json.dumps(finite(rep), allow_nan=False), flush=True)
    except (OSError, FydpadError, ValueError) as e:  # ArmFault is a FydpadError
        print(f"teleop slave: {e}", file=sys.stderr)
        return 2
    except Exception as e:  # a fault in the loop or the link: the robot is stopped (finally)
        log.exception("slave loop fault")
        print(f"teleop slave: stopped the robot on a fault: {type(e).__name__}: {e}",
              file=sys.stderr)
        return 1
    finally:
        arm.close()
        signal.signal(signal.SIGTERM, old_handlers[0])
        signal.signal(signal.SIGINT, old_handlers[1])
    return 0


def _cmd_keys(args: argparse.Namespace) -> int:
    from teleop.keys import generate  # loads ZeroMQ: not for --help

    try:
        files = generate(Path(args.dir))
    except FileExistsError as e:
        print(f"teleop keys: {e}", file=sys.stderr)
        return 2
    for f in files:
        print(f)
    print(f"copy {args.dir}/server.key and the client pair to the master; keep "
          "server.key_secret on the slave only")
    return 0


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="teleop",
        description="FYD-pad tele-operation: the finger on the pad drives a robot arm over "
                    "ZeroMQ (docs/teleop.md, docs/protocol.md).")
    ap.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = ap.add_subparsers(dest="command", required=True)
    s = sub.add_parser("slave", help="run a slave robot until Ctrl-C",
                       description="Bind ENDPOINT, follow the master's samples with the robot; "
                                   "Ctrl-C stops the robot and writes the report.")
    s.add_argument("--robot", choices=("sim", "ur"), default="sim",
                   help="sim: PyBullet KUKA iiwa (default); ur: Universal Robots via ur-rtde "
                        "(with --ur-host sim: a UR5e in MuJoCo behind the same ur-rtde calls, "
                        "the mujoco extra; docs/teleop.md)")
    s.add_argument("--bind", required=True,
                   help="ZeroMQ endpoint, e.g. tcp://0.0.0.0:5555 or tcp://127.0.0.1:* "
                        "(random port, printed)")
    s.add_argument("--report", metavar="FILE", help="write the slave's counts as JSON here")
    s.add_argument("--config", metavar="FILE",
                   help="the device file (`fydpad config show`): its [teleop.*] tables; the "
                        "other sections are the station's and are skipped")
    s.add_argument("--ur-host", help="UR controller address (with --robot ur); 'sim': the "
                                     "simulated UR5e controller (MuJoCo)")
    s.add_argument("--curve", choices=("auto", "on", "off"),
                   help="CurveZMQ: auto = on unless the endpoint is loopback")
    s.add_argument("--keys", metavar="DIR", help="CurveZMQ key directory")
    s.add_argument("--rt-priority", type=int, metavar="N",
                   help="SCHED_FIFO priority 1-99 for the slave's loop and link threads, 0 for "
                        "normal scheduling (default: link.rt_priority = 50). Refused without "
                        "the right to it (root, CAP_SYS_NICE or an rtprio limit): the slave "
                        "then runs at normal priority and says so")
    s.add_argument("--duration", type=float, help=argparse.SUPPRESS)  # tests
    s.set_defaults(func=_cmd_slave)
    k = sub.add_parser("keys", help="CurveZMQ key files")
    ksub = k.add_subparsers(dest="keys_command", required=True)
    g = ksub.add_parser("generate", help="create server and client key pairs in DIR")
    g.add_argument("dir", metavar="DIR")
    g.set_defaults(func=_cmd_keys)
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO,
                        format="%(asctime)s %(name)s %(levelname)s: %(message)s")
    return int(args.func(args))


if __name__ == "__main__":
    sys.exit(main())
