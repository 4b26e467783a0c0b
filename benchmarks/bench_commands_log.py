"""The render tick with its commands log written into a slow sink.

Runs the real render process (``fydpad.station.render.render_main``) for a few seconds
in each case and prints how late its ticks started: p50/p99 (ticks that ran), ticks
skipped (the loop fell a whole period behind: a tick held up by the log), the share on
time over all scheduled ticks, and p99 over the baseline's p99 measured in the same run.

- baseline: no commands log;
- file: the log into a file in a temporary folder;
- stalled pipe: the log into a FIFO whose reader sleeps ``--stall`` s between reads (its
  buffer cut to one page): a disk that stalls, as a full page cache or a slow USB stick.

Usage: python benchmarks/bench_commands_log.py [--seconds S] [--stall S] [--no-realtime]
Runs on any checkout whose RenderSpec has ``commands_csv`` (compare two commits with
``PYTHONPATH=<checkout> python benchmarks/bench_commands_log.py``).
"""

from __future__ import annotations

import argparse
import fcntl
import math
import multiprocessing as mp
import os
import tempfile
import threading
import time
from pathlib import Path

from fydpad.station.render import CONTROL_FIELDS, RenderSpec, render_main
from fydpad.station.shared import SharedFingerState, SharedRecord
from vision.state import FingerState

F_SETPIPE_SZ = 1031


class SleepyReader:
    """Reads a FIFO, sleeping ``stall_s`` between reads: the slow sink."""

    def __init__(self, path: Path, stall_s: float) -> None:
        os.mkfifo(path)
        self.fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        fcntl.fcntl(self.fd, F_SETPIPE_SZ, 4096)
        self.stall_s = stall_s
        self.bytes = 0
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.stop.wait(self.stall_s):
            try:
                while chunk := os.read(self.fd, 1 << 20):
                    self.bytes += len(chunk)
            except BlockingIOError:
                pass
        os.set_blocking(self.fd, True)
        while chunk := os.read(self.fd, 1 << 20):  # to the writer's close
            self.bytes += len(chunk)

    def close(self) -> None:
        self.stop.set()
        self.thread.join(60)
        os.close(self.fd)


def run_case(commands_csv: str | None, seconds: float, realtime: bool) -> dict:
    ctx = mp.get_context("spawn")
    state = SharedFingerState()
    state.publish(FingerState(t_s=0.0, contact=True, x_mm=1.0, y_mm=2.0), 0.0, 0)
    control = SharedRecord(CONTROL_FIELDS)
    values = [1.0, math.nan, 1.0, time.perf_counter(), 0.0, math.nan]
    control.write(values + [0.0] * (len(CONTROL_FIELDS) - len(values)))  # any checkout
    stop, ready, results = ctx.Event(), ctx.Event(), ctx.Queue()
    spec = RenderSpec(realtime=realtime, commands_csv=commands_csv)
    p = ctx.Process(target=render_main, args=(spec, state, control, stop, results, ready))
    p.start()
    ready.wait(120)
    time.sleep(seconds)
    stop.set()
    while True:
        kind, payload = results.get(timeout=120)
        if kind == "stats":
            break
        if kind == "fault":
            print("fault:", payload.splitlines()[0])
    p.join(60)
    return payload["render"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--stall", type=float, default=1.0,
                    help="seconds the pipe's reader sleeps between reads")
    ap.add_argument("--no-realtime", action="store_true",
                    help="no SCHED_FIFO for the render process")
    args = ap.parse_args()
    rt = not args.no_realtime
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        rows.append(("baseline: no log", run_case(None, args.seconds, rt)))
        rows.append(("file", run_case(str(Path(tmp) / "c.csv"), args.seconds, rt)))
        fifo = Path(tmp) / "pipe.csv"
        reader = SleepyReader(fifo, args.stall)
        rows.append((f"pipe, reader sleeps {args.stall:g} s",
                     run_case(str(fifo), args.seconds, rt)))
        reader.close()
    base_p99 = rows[0][1]["jitter_ms"]["p99"]
    print(f"render process, {args.seconds:g} s a case, scheduling: "
          f"{rows[0][1].get('scheduling', '?')}")
    print(f"{'commands log':<28}{'p50 ms':>8}{'p99 ms':>8}{'skipped':>9}{'on time %':>11}"
          f"{'p99 / baseline':>16}{'rows lost':>11}")
    for name, s in rows:
        scheduled = s["ticks"] + s["skipped"]
        on_time = 100.0 * s["on_time_pct"] / 100.0 * s["ticks"] / scheduled
        lost = s.get("commands_log", {}).get("dropped", "-")
        print(f"{name:<28}{s['jitter_ms']['p50']:>8.2f}{s['jitter_ms']['p99']:>8.2f}"
              f"{s['skipped']:>9d}{on_time:>11.2f}{s['jitter_ms']['p99'] / base_p99:>15.2f}x"
              f"{lost!s:>11}")


if __name__ == "__main__":
    main()
