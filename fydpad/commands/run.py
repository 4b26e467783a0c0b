"""``fydpad run``: the master station, live or on a replayed recording."""

from __future__ import annotations

# Libraries are imported inside the command functions, so that --help starts fast.
import argparse
import json
import math
import os
import signal
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from fydpad.cli import add_config_argument, add_truncation_argument
from fydpad.errors import UserError

if TYPE_CHECKING:  # annotations only: the station loads inside the command
    from fydpad.station.station import Station
    from fydpad.texture.family import TextureFamily

def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "run",
        help="run the master station (live camera or a replayed recording)",
        description=(
            "Run the FYD-pad master station: each loop at its own rate (vision at the camera "
            "rate, IR and force at the sensor rate, rendering at 1 kHz in a process of its "
            "own, tele-operation at the vision rate), handing each other the latest value. "
            "Ctrl-C, --duration or any fault stops it safely: vibration off, motors to rest, "
            "robot told to hold, files closed. A second Ctrl-C forces the exit. "
            "Operator hold: in the terminal, h or the space bar holds the robot still and "
            "silences the vibration, the same key releases (the robot glides back to the "
            "finger); also the web view's Hold button and the sensor board's pedal "
            "(docs/station.md)."
        ),
    )
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--camera", metavar="N", help="live camera (index or device path)")
    src.add_argument("--replay", metavar="RECDIR", help="replay a pad session recording")
    src.add_argument("--synthetic", metavar="TRAJECTORY", nargs="?", const="walk",
                     help="the simulated pad, rendered live (a trajectory of `fydpad synth`: "
                     "circle, lissajous, tapping, walk (default), fast, hover)")
    p.add_argument("--duration", type=float, metavar="S",
                   help="stop after S seconds; a --replay shorter than that holds on its last "
                   "frame (the robot holding still) until then, or with --loop starts again")
    p.add_argument("--loop", action="store_true",
                   help="with --replay and --duration: restart the recording (frames, IR and "
                   "force) at its end until --duration")
    p.add_argument("--sensors", metavar="serial:PORT[@BAUD]",
                   help="read IR and force from the serial sensor board "
                   "(docs/sensor_board_protocol.md) instead of the source's own; default: "
                   "[endpoints] sensors of the config, else the replay's ir.csv/force.csv or "
                   "the synthetic pad's. A board that stops sending stops the station safely")
    p.add_argument("--vision-hz", type=float, metavar="HZ",
                   help="track at this rate (the paper: 10), dropping the frames in between; "
                   "tele-operation follows at the same rate (default: [loops] vision_hz of "
                   "the config, 30, or the camera's rate when lower)")
    p.add_argument("--record", metavar="DIR",
                   help="record the session (docs/recording_format.md) as it goes")
    p.add_argument("--no-video", action="store_true", help="with --record: no video file")
    p.add_argument("--bag", metavar="BAGDIR",
                   help="with --record: when the station stops, also export the recording as "
                   "a ROS 2 bag (MCAP) here, as `fydpad export bag` does (docs/ros.md)")
    p.add_argument("--stats", metavar="FILE", help="write loop statistics as JSON on exit")
    p.add_argument("--motors", choices=["none", "sim", "qb"], default="none",
                   help="motor backend (default: %(default)s)")
    p.add_argument("--texture", metavar="[KIND:]MODEL",
                   help="render this texture model (kind lpc, friction, grating or mlp, read "
                   "from the file; KIND: checks it). lpc and mlp drive the vibration term; "
                   "friction and grating drive it by position and scale the softness "
                   "stiffness through the tension channel (docs/texture_families.md)")
    p.add_argument("--compensate", metavar="TF.npz",
                   help="pre-compensate the vibration term by the inverse of the actuator "
                   "chain's TF (`fydpad chain identify`; the entry nearest the rendered "
                   "stiffness; docs/chain.md)")
    p.add_argument("--channel", action="append", default=[], metavar="[SIGNAL=]TARGET",
                   help="also send a texture signal to an output channel (repeatable): TARGET "
                   "wav:FILE, csv:FILE or audio[:DEVICE][@RATE] (the sound card); SIGNAL "
                   "vibration (eq. 3's texture term at 1 kHz, the default for files) or a "
                   "channel the family declares, e.g. audio (friction's V = b mu(x) Y(t), a "
                   "grating's V_e, at 48 kHz; the default for the sound card where the "
                   "family has it); ',fs=X' sets the full scale of WAV and card (default 1). "
                   "Stop or fault silences the card (docs/channels.md)")
    p.add_argument("--teleop", metavar="ENDPOINT",
                   help="stream the finger to a slave robot (`teleop slave`) at this endpoint "
                   "(tcp://HOST:PORT or HOST:PORT). A slave that never answers or goes "
                   "silent leaves the station running (the robot holds by its watchdog); the "
                   "run then ends with a line saying so and exit status 3")
    add_link_arguments(p)
    p.add_argument("--vibration-gain", type=float, default=1.0,
                   help="texture vibration gain (the paper: 1)")
    p.add_argument("--drive-filter", action="store_true",
                   help="band-pass an LPC model's vibration through its file's drive band "
                   "(the paper's 165-220 Hz, where the fabric's actuators respond)")
    soft = p.add_mutually_exclusive_group()
    soft.add_argument("--softness", type=float, metavar="N_PER_MM",
                      help="render this stiffness (N/mm)")
    soft.add_argument("--specimen", metavar="NAME",
                      help="render a characterised specimen's stiffness (SS1..SS4: the paper's)")
    p.add_argument("--as-fast-as-possible", action="store_true",
                   help="with --replay: do not pace the frames at their recorded times")
    p.add_argument("--no-realtime", action="store_true",
                   help="do not ask for SCHED_FIFO and a core for the render process")
    add_config_argument(p)
    add_truncation_argument(p)
    # -- web view --
    p.add_argument("--web", metavar="[HOST:]PORT",
                   help="serve the web view (live image, plots, setup, experiment runner); "
                   "loopback unless HOST is given, then with a token printed at start")
    p.add_argument("--web-results", metavar="DIR", default="experiment-results",
                   help="with --web: the experiment results directory, created when the "
                   "first participant's session starts, its path printed then (default: "
                   "%(default)s)")
    p.add_argument("--web-stimuli", metavar="FILE.json",
                   help="with --web: the experiment's stimuli (name, stiffness, texture model; "
                   "docs/experiment.md); default: the paper's SS1-SS4 with grating models")
    # -- end web view --
    p.set_defaults(func=run)


def _model_cache() -> Path:
    """Where derived texture models are written: $XDG_CACHE_HOME/fydpad (~/.cache/fydpad)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "fydpad"


class ExtendedReplay:
    """A replay's frames, then (``loop``) the recording again, shifted in time, or its last
    frame repeated at the recording's rate, until ``duration_s``: the station and its web
    view stay up for the whole --duration."""

    def __init__(self, source, period_s: float, duration_s: float | None, loop: bool):
        self.source = source
        self.period_s = period_s
        self.duration_s = duration_s
        self.loop = loop

    def __getattr__(self, name: str):
        return getattr(self.source, name)

    def frames(self):
        from vision.sources import Frame

        offset_s, k, last = 0.0, 0, None
        while True:
            for frame in self.source.frames():
                last = frame
                yield Frame(k, offset_s + frame.t_s, frame.image)
                k += 1
            if last is None or self.duration_s is None:
                return
            end_s = offset_s + last.t_s + self.period_s
            if self.loop and end_s < self.duration_s:
                offset_s = end_s
                continue
            t_s = end_s
            while t_s <= self.duration_s:  # hold on the last frame
                yield Frame(k, t_s, last.image)
                k += 1
                t_s += self.period_s
            return


def _tiled(samples, period_s: float, times: int):
    """(t_s, values) repeated ``times`` times, each copy ``period_s`` later."""
    if samples is None:
        return None
    import numpy as np

    t, v = samples
    return (np.concatenate([t + i * period_s for i in range(times)]),
            np.concatenate([v] * times))


def _extended_replay(args: argparse.Namespace, rec, source):
    """The replay's source and sensor feed for --duration and --loop."""
    from fydpad.station.station import SensorFeed

    if args.loop and args.duration is None:
        raise UserError("--loop needs --duration S (how long to keep replaying)")
    period_s = 1.0 / rec.fps
    length_s = rec.frame_count * period_s
    sensors = SensorFeed(rec.read_ir(), rec.read_force())
    if args.loop:
        times = max(1, math.ceil(args.duration / length_s) + 1)
        sensors = SensorFeed(_tiled(rec.read_ir(), length_s, times),
                             _tiled(rec.read_force(), length_s, times))
    return ExtendedReplay(source, period_s, args.duration, args.loop), sensors


def add_link_arguments(p: argparse.ArgumentParser) -> None:
    """The master's side of the link's security: --curve and --keys (docs/getting_started.md)."""
    p.add_argument("--curve", choices=("auto", "on", "off"),
                   help="CurveZMQ on the tele-operation link: auto = on unless the endpoint is "
                   "loopback (default: [teleop.link] curve of the config, auto)")
    p.add_argument("--keys", metavar="DIR",
                   help="CurveZMQ key directory holding server.key, client.key and "
                   "client.key_secret from the slave's `teleop keys generate DIR` (default: "
                   "[teleop.link] keys_dir of the config, teleop_keys)")


def apply_link_arguments(args: argparse.Namespace, config) -> None:
    """--curve and --keys over the config's [teleop.link]."""
    if args.curve:
        config.teleop.link.curve = args.curve
    if args.keys:
        config.teleop.link.keys_dir = args.keys


def open_link(endpoint: str, config):
    """The station's link; a missing key file or a bad endpoint is one line."""
    from fydpad.station.link import StationLink

    try:
        return StationLink(endpoint, config.teleop)
    except (OSError, ValueError) as exc:
        raise UserError(f"--teleop {endpoint}: {exc}") from None


class LinkWatch:
    """What the run tells at its end about the link: whether the slave ever answered, and
    how often and how long it went silent (LINK_SILENT_S without an answer) after that."""

    def __init__(self) -> None:
        self.outages = 0
        self.longest_silence_s = 0.0
        self._silent = False

    def update(self, answered: bool, age_s: float) -> None:
        if not answered:
            return
        if age_s > LINK_SILENT_S:
            self.longest_silence_s = max(self.longest_silence_s, age_s)
            if not self._silent:
                self.outages += 1
                self._silent = True
        else:
            self._silent = False

    def summary(self, endpoint: str, answered: bool, sent: int, failed: int) -> str | None:
        """None for a link that held; else the line that says what went wrong."""
        if not answered:
            return (f"tele-operation link {endpoint}: no slave ever answered ({sent} samples "
                    f"sent, {failed} refused for want of a connection): is `teleop slave` "
                    "running there, its port open, and are the CurveZMQ settings and keys the "
                    "same on both sides?")
        if self.outages:
            return (f"tele-operation link {endpoint}: the slave went silent {self.outages} "
                    f"time(s), the longest {self.longest_silence_s:.1f} s; the robot held "
                    "meanwhile (its watchdog)")
        return None


class _Interrupts:
    """First Ctrl-C: stop safely. Second: exit at once."""

    def __init__(self) -> None:
        self.station: Station | None = None
        self.count = 0

    def __call__(self, signum, frame) -> None:
        self.count += 1
        if self.count == 1 and self.station is not None:
            print("\nstopping (Ctrl-C again to force)", file=sys.stderr)
            self.station.stop_event.set()
        else:
            os._exit(130)


#: A slave that has not answered for this long is reported silent in the status line.
LINK_SILENT_S = 1.0


def _num(value: object, spec: str, width: int = 0) -> str:
    """``value`` formatted by ``spec``, or "-" (right-aligned to ``width``) when there is
    none yet: no NaN where a user reads."""
    if isinstance(value, int | float) and math.isfinite(value):
        return format(value, spec)
    return "-".rjust(width)


def format_status(s: dict) -> str:
    """The live status line: rates and jitter, contact, indentation, force, requested and
    measured stiffness, the link and the sensor board; "-" for a value not known yet."""
    contact = (f"contact x {_num(s['x_mm'], '+6.1f', 6)} y {_num(s['y_mm'], '+6.1f', 6)} mm"
               if s["contact"] else "no contact" + " " * 20)
    r = s.get("render") or {}
    v = s.get("vision") or {}
    line = (f"frames {s['frames']:6d}  {contact}  z {_num(s['indentation_mm'], '5.1f', 5)} mm  "
            f"F {_num(s['force_n'], '5.2f', 5)} N  "
            f"k {_num(s['measured_n_per_mm'], '.2f')}/{_num(s['requested_n_per_mm'], '.2f')} "
            f"N/mm  "
            f"vision {_num(v.get('rate_hz'), '4.1f', 4)} Hz  "
            f"render {_num(r.get('rate_hz'), '6.1f', 6)} Hz "
            f"{_num(r.get('on_time_pct'), '5.1f', 5)} % on time "
            f"p99 {_num(r.get('jitter_ms', {}).get('p99'), '.2f')} ms")
    link = s.get("link")
    if link is not None:
        age_s = link.get("answer_age_s", 0.0)
        if link["send_failed"]:
            state = f"{link['send_failed']} failed"
        elif not link["slave_answered"]:
            state = "no answer"
        elif age_s > LINK_SILENT_S:
            state = f"silent {age_s:.0f} s"
        else:
            state = "ok"
        line += f"  link {state}"
    if s.get("operator_hold"):
        line += "  HOLD"
    board = s.get("sensors")
    if board is not None:
        line += f"  board {board['samples']} ok {board['bad_lines']} bad"
    return line


def _status_printer():
    if not sys.stderr.isatty():
        return None

    def show(s: dict) -> None:
        print("\r" + format_status(s) + " ", end="", file=sys.stderr, flush=True)

    return show


def _synthetic(args: argparse.Namespace, config):
    """The synthetic pad as the station's camera, IR board and load cell."""
    from fydpad.station.station import SensorFeed
    from fydpad.synth import SynthConfig, SyntheticPad
    from fydpad.synth.sources import SynthFrameSource

    try:
        cfg = SynthConfig(trajectory=args.synthetic, seconds=args.duration or 60.0,
                          roi_px=config.camera.roi_px, workspace_mm=config.camera.workspace_mm,
                          image_flip=config.camera.image_flip)
        pad = SyntheticPad(cfg)
    except ValueError as exc:
        raise UserError(f"--synthetic: {exc}") from None
    return SynthFrameSource(pad), pad.meta(), SensorFeed(pad.ir(), pad.force())


def _serial_sensors(spec: str, config):
    """The serial IR + load-cell board as the station's sensor feed."""
    from fydpad.station.station import SerialSensorFeed
    from vision.sensors import SensorError, SerialBoard, parse_serial_spec

    try:
        port, baud = parse_serial_spec(spec)
        board = SerialBoard(port, baud, ir_config=config.ir, force_config=config.force,
                            timeout_s=config.ir.serial_timeout_s)
    except (ValueError, SensorError) as exc:
        raise UserError(f"--sensors: {exc}") from None
    return SerialSensorFeed(board)


def _stiffness(args: argparse.Namespace) -> float:
    if args.specimen is not None:
        from fydpad.softness import specimen

        return specimen(args.specimen).lambda_n_per_mm
    return math.nan if args.softness is None else args.softness


def _say_texture_gaps(family: TextureFamily, spec: str) -> None:
    """One line at start when a texture's scans left speeds unscanned (its model
    interpolates there: docs/texture.md, 'Speed coverage')."""
    from fydpad.texture.lpc.coverage import describe

    gaps = family.unscanned_speeds()
    if gaps:
        print(f"texture {spec}: no scan between {describe(gaps)}; the texture felt there is "
              "the model's interpolation (docs/texture.md, 'Speed coverage')", file=sys.stderr)


def _check_channels(args: argparse.Namespace, render_hz: float) -> None:
    """--channel: the spec parses, the texture renders its signal, the card is there. The
    channels themselves are opened by the render process."""
    from fydpad.channels import ChannelError
    from fydpad.station.outputs import check_channel

    if not args.texture or args.motors == "none":
        raise UserError("--channel needs a texture to render: --texture MODEL and "
                        "--motors sim or qb")
    from fydpad.texture.families import load_family

    family = load_family(args.texture)
    for text in args.channel:
        try:
            check_channel(text, [family], render_hz)
        except ChannelError as exc:
            raise UserError(str(exc)) from None


def run(args: argparse.Namespace) -> int:
    from fydpad.commands.track import make_tracker
    from fydpad.config import load_config
    from fydpad.opening import open_source
    from fydpad.station.render import RenderSpec
    from fydpad.station.station import SensorFeed, Station, StationFault, StationOptions
    from vision.indentation import IndentationEstimator
    from vision.stream import LiveIndentation, recording_estimator
    from vision.strict_json import finite

    config = load_config(args.config)
    camera = None
    indentation = None
    if args.synthetic is not None:
        source, meta, sensors = _synthetic(args, config)
        indentation = LiveIndentation(IndentationEstimator.from_config(config.ir))
    else:
        opened = open_source(config, args.replay, args.camera)
        source, meta, rec, camera = opened.source, opened.meta, opened.recording, opened.camera
        sensors = SensorFeed(rec.read_ir(), rec.read_force()) if rec is not None else None
        if rec is not None:
            source, sensors = _extended_replay(args, rec, source)
        if rec is not None and rec.has("ir.csv"):
            indentation = LiveIndentation(recording_estimator(rec, config.ir))
    tracker = make_tracker(config.tracker, meta.roi_px, meta.workspace_mm, meta.image_flip,
                           camera)
    vision_hz = config.loops.vision_hz if args.vision_hz is None else args.vision_hz
    if not (math.isfinite(vision_hz) and vision_hz > 0):
        raise UserError(f"--vision-hz {vision_hz:g}: must be a positive rate in Hz")
    sensor_spec = args.sensors or config.endpoints.sensors
    if sensor_spec:  # the live board replaces the source's own IR and force
        sensors = _serial_sensors(sensor_spec, config)
        indentation = LiveIndentation(IndentationEstimator.from_config(config.ir))
    if args.bag:  # --bag: refused here, before the station starts, not after the session
        from fydpad.commands.export import require_rosbags

        if not args.record:
            raise UserError("--bag needs --record DIR (the bag is exported from the recording)")
        if Path(args.bag).exists():
            raise UserError(f"--bag {args.bag}: already exists (a bag is written to a new "
                            "directory)")
        require_rosbags()
    if args.record:
        Path(args.record).mkdir(parents=True, exist_ok=True)
    if args.loop and args.replay is None:
        raise UserError("--loop applies to --replay")
    if args.teleop is None and (args.curve or args.keys):
        raise UserError("--curve and --keys apply to the tele-operation link: give --teleop")
    if args.texture:  # a bad model file fails here, in one line, not in the render process
        from fydpad.station.texture_source import check_texture

        family = check_texture(args.texture, config.loops.render_hz,
                               args.drive_filter)  # a wrong rate would play a wrong pitch
        _say_texture_gaps(family, args.texture)
    elif args.drive_filter:
        raise UserError("--drive-filter needs --texture MODEL")
    if args.compensate:  # a TF file of another chain fails here, in one line
        from fydpad.chain.tf_file import load_tf_set

        load_tf_set(args.compensate, config.loops.render_hz, "vibration")
    if args.channel:  # a bad spec, signal or device fails here, in one line
        _check_channels(args, config.loops.render_hz)
    render = RenderSpec(
        rate_hz=config.loops.render_hz,
        texture=args.texture,
        vibration_gain=args.vibration_gain,
        drive_filter=args.drive_filter,
        stiffness_n_per_mm=_stiffness(args),
        motors=args.motors,
        commands_csv=str(Path(args.record) / "commands.csv") if args.record else None,
        realtime=not args.no_realtime,
        config=config,
        compensate=args.compensate,
        channels=tuple(args.channel),
    )
    options = StationOptions(
        duration_s=args.duration, real_time=not args.as_fast_as_possible, vision_hz=vision_hz,
        record_dir=args.record, record_video=not args.no_video, render=render,
        status=_status_printer(),
    )
    link = None
    watch = LinkWatch()
    if args.teleop:
        apply_link_arguments(args, config)
        link = open_link(args.teleop, config)
        options.teleop_hold = link.hold
        options.operator_hold = link.set_operator_hold
    station = Station(source, tracker, meta, options, sensors=sensors, indentation=indentation,
                      force_full_scale_n=config.force.full_scale_n)
    if link is not None:
        def send(state, link=link, station=station) -> None:
            link.send(state)
            watch.update(link.slave is not None, link.answer_age_s())
            # For the web view and the status: the robot's tracking error, as it is now.
            station.live_stats["link"] = {
                "endpoint": link.endpoint, "sent": link.sent, "send_failed": link.send_failed,
                "slave_answered": link.slave is not None,
                "answer_age_s": round(min(link.answer_age_s(), 1e9), 3),
                "tracking_error_mm": (round(err, 2) if math.isfinite(
                    err := link.tracking_error_mm(state)) else None),
            }
        options.teleop_send = send
    # -- web view --
    web = None
    if getattr(args, "web", None):
        from fydpad.web.server import parse_web_address, start_web
        from fydpad.web.stimuli import experiment_stimuli

        try:
            web_host, web_port = parse_web_address(args.web)
            # The grating models the stimuli render are derived files: they go to the
            # user's cache, so --web-results is created only by the first result written.
            stimuli = experiment_stimuli(args.web_stimuli, _model_cache())
            if args.motors != "none":  # every stimulus's texture, loaded by the render process
                render.textures = tuple(dict.fromkeys(s.texture for s in stimuli if s.texture))
            web = start_web(station, config, args.config, web_host, web_port,
                            results_dir=args.web_results, stimuli=stimuli)
        except (ValueError, OSError) as exc:
            raise UserError(str(exc)) from None
        print(f"web view: {web.url}", file=sys.stderr, flush=True)
    # -- end web view --
    interrupts = _Interrupts()
    interrupts.station = station
    previous = signal.signal(signal.SIGINT, interrupts)
    # A service manager's SIGTERM stops the station the same safe way as Ctrl-C.
    previous_term = signal.signal(signal.SIGTERM, interrupts)
    from fydpad.station.hold_keys import HoldKeys

    keys = HoldKeys(lambda: station.toggle_operator_hold("key"))
    try:
        with keys:
            if keys.active:
                print("press h or space to hold the robot (again to release)",
                      file=sys.stderr, flush=True)
            stats = station.run()
    except StationFault as exc:
        raise UserError(f"station stopped safely after a fault: {exc}") from None
    finally:
        signal.signal(signal.SIGINT, previous)
        signal.signal(signal.SIGTERM, previous_term)
        if web is not None:  # web view
            web.stop()
        link_summary = None
        if link is not None:
            link_summary = watch.summary(link.endpoint, link.slave is not None, link.sent,
                                         link.send_failed)
            station.stats["link"] = {"sent": link.sent, "send_failed": link.send_failed,
                                     "slave_answered": link.slave is not None,
                                     "outages": watch.outages,
                                     "longest_silence_s": round(watch.longest_silence_s, 3)}
            link.close()
        if options.status is not None:
            print(file=sys.stderr)
        if args.stats:
            Path(args.stats).write_text(
                json.dumps(finite(station.stats), indent=2, allow_nan=False) + "\n")
    r = stats.get("render", {})
    dropped = (f", {station.frames_dropped} dropped for --vision-hz"
               if station.frames_dropped else "")
    camera_failures = stats.get("vision", {}).get("camera_read_failures")
    if camera_failures:  # a live camera's dropped frames: counted, not fatal
        dropped += (f", {camera_failures} dropped by the camera in "
                    f"{stats['vision']['camera_outages']} outages")
    print(f"station ran {station.frames} frames ({station.contact_frames} with contact"
          f"{dropped}); "
          f"render {r.get('rate_hz', 0):.1f} Hz, {r.get('on_time_pct', 0):.2f} % on time, "
          f"jitter p99 {_num(r.get('jitter_ms', {}).get('p99'), '.2f')} ms, "
          f"frame-to-command p99 "
          f"{_num(stats.get('frame_to_command_ms', {}).get('p99'), '.1f')} ms")
    if args.bag:
        from fydpad.commands.export import export_recording

        print(export_recording(args.record, args.bag, args.config, video=not args.no_video))
    if link_summary is not None:
        print(f"fydpad run: {link_summary}", file=sys.stderr)
        return 3
    return 0
