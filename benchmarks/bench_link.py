"""Link benchmark: one-way latency p50/p99 and lost samples at 1 kHz on loopback.

Runs `teleop slave --robot sim` in its own process on a random loopback port and streams a
40 mm/s circle sampled at --rate Hz for --duration s through the master API; prints the
figures. Targets: p99 <= 2 ms, no sample lost at 1 kHz for 60 s.

    python benchmarks/bench_link.py                  # 60 s at 1 kHz
    python benchmarks/bench_link.py --duration 10 --curve   # with CurveZMQ
    python benchmarks/bench_link.py --raw            # the link alone: a bare echo slave
    python benchmarks/bench_link.py --rt-priority 0  # both processes at normal priority

Both processes ask for SCHED_FIFO (--rt-priority, default 50, as `teleop slave` does by
default; teleop/realtime.py): on a shared machine, at normal priority, a process waits for
a CPU for 100 ms and more and the master's queue refuses samples meanwhile.

--raw replaces the robot slave by a process that only decodes each sample and
acknowledges it: the link's own latency, without the slave loop's physics and IK.

Besides the report's latency (clock offset from the echo with the shortest round trip,
as between two machines), the same figures from the one clock both processes share here
(CLOCK_MONOTONIC: slave's receive time - master's send time, no offset), the machine's
load average before and after (the other processes on a shared machine) and the CPU time
the benchmark's processes used (a busy-waiting loop shows here).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from teleop.config import LinkConfig  # noqa: E402
from teleop.link import MasterSocket  # noqa: E402
from teleop.master import stream  # noqa: E402
from teleop.realtime import request_realtime  # noqa: E402
from teleop.trajectories import circle, finger_stream  # noqa: E402


def raw_echo(endpoint_q, stop_s: float, link: LinkConfig) -> None:
    """A bare slave: ROUTER (CurveZMQ per ``link``), decode, acknowledge at once."""
    from teleop import protocol as P
    from teleop.link import SlaveSocket
    slave = SlaveSocket("tcp://127.0.0.1:*", link)
    sock = slave.sock
    endpoint_q.put(slave.endpoint)
    received = 0
    t_end = time.monotonic() + stop_s
    while time.monotonic() < t_end:
        if not sock.poll(100):
            continue
        ident, buf = sock.recv_multipart()
        t_recv = time.monotonic()
        try:
            s = P.decode_sample(buf)
        except P.ProtocolError:
            continue
        received += 1
        st = P.State(1, P.REASON_ACK, s.seq, s.t_send_s, t_recv, time.monotonic(),
                     (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), received, 0)
        sock.send_multipart([ident, P.encode_state(st)])
    slave.close()


def same_clock_ms(log) -> np.ndarray:
    """One-way latency per acknowledged sample on one host's monotonic clock."""
    from teleop import protocol as P
    seen: dict[int, float] = {}
    for _, st in log.states:
        if st.reason == P.REASON_ACK and st.echo_seq not in seen:
            seen[st.echo_seq] = st.t_echo_recv_s - st.t_echo_send_s
    return np.array(list(seen.values())) * 1e3


def print_latency(log, load_before: tuple[float, float, float]) -> None:
    for name, lat_ms in (("one-way latency ms (echo offset)", log.latencies_s() * 1e3),
                         ("one-way latency ms (same clock) ", same_clock_ms(log))):
        print(f"{name}: p50 {np.percentile(lat_ms, 50):.3f}  p99 {np.percentile(lat_ms, 99):.3f}"
              f"  max {lat_ms.max():.3f}  (n={lat_ms.size})")
    ru = [resource.getrusage(w) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)]
    cpu = sum(r.ru_utime + r.ru_stime for r in ru)
    print(f"load average before {' '.join(f'{x:.2f}' for x in load_before)}, after "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())} (1, 5, 15 min; "
          f"{os.cpu_count()} cores); CPU used by master + slave {cpu:.1f} s")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--rate", type=float, default=1000.0)
    ap.add_argument("--curve", action="store_true", help="CurveZMQ on (keys in a temp dir)")
    ap.add_argument("--raw", action="store_true", help="bare echo slave: the link alone")
    ap.add_argument("--rt-priority", type=int, default=50,
                    help="SCHED_FIFO priority of master and slave, 0 = normal (default 50)")
    args = ap.parse_args()
    load_before = os.getloadavg()
    # Before any ZeroMQ context exists (its I/O threads inherit it; so does --raw's child).
    print(f"master scheduling: {request_realtime(args.rt_priority)}")
    if args.raw:
        return run_raw(args, load_before)
    tmp = Path(tempfile.mkdtemp())
    cmd = [sys.executable, "-m", "teleop.cli", "slave", "--robot", "sim",
           "--bind", "tcp://127.0.0.1:*", "--report", str(tmp / "slave.json"),
           "--rt-priority", str(args.rt_priority)]
    link = LinkConfig()
    if args.curve:
        from teleop.keys import generate
        generate(tmp / "keys")
        cmd += ["--curve", "on", "--keys", str(tmp / "keys")]
        link = LinkConfig(curve="on", keys_dir=str(tmp / "keys"))
    slave = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True, cwd=REPO)
    try:
        line = ""
        while "listening on" not in line:
            line = slave.stdout.readline()
            if not line and slave.poll() is not None:
                raise SystemExit("slave did not start")
        endpoint = line.split("listening on ")[1].split()[0]
        states, _ = finger_stream(circle(), args.duration, fps=args.rate, noise_mm=0.05)
        with MasterSocket(endpoint, link) as sock:
            time.sleep(0.5)
            t0 = time.monotonic()
            log = stream(states, sock, preroll_s=0.2)
            wall = time.monotonic() - t0
        acks = [st for _, st in log.states]
        delivered = acks[-1].received - acks[0].received + 1 if acks else 0
    finally:
        slave.send_signal(2)
        slave.communicate(timeout=20)
        slave.wait()
    rep = json.loads((tmp / "slave.json").read_text())
    lost = log.sent + log.send_failed - rep["received"]
    print(f"rate {args.rate:.0f} Hz, {args.duration:.0f} s ({wall:.1f} s wall), "
          f"curve {'on' if args.curve else 'off'}, slave scheduling {rep.get('scheduling')}")
    print(f"sent {log.sent}, send refused {log.send_failed}, slave received {rep['received']}"
          f" (seen by acks {delivered}), accepted {rep['accepted']}, lost {lost}, "
          f"dropped by slave {rep['dropped']}")
    print_latency(log, load_before)
    return 0


def run_raw(args: argparse.Namespace, load_before: tuple[float, float, float]) -> int:
    import multiprocessing as mp
    link = LinkConfig()
    if args.curve:
        from teleop.keys import generate
        keys = Path(tempfile.mkdtemp()) / "keys"
        generate(keys)
        link = LinkConfig(curve="on", keys_dir=str(keys))
    q: mp.Queue = mp.Queue()
    proc = mp.Process(target=raw_echo, args=(q, args.duration + 5.0, link))
    proc.start()
    try:
        endpoint = q.get(timeout=10)
        states, _ = finger_stream(circle(), args.duration, fps=args.rate, noise_mm=0.05)
        with MasterSocket(endpoint, link) as sock:
            time.sleep(0.3)
            log = stream(states, sock, preroll_s=0.0)
    finally:
        proc.terminate()
        proc.join(5)
    got = max((st.received for _, st in log.states), default=0)
    print(f"raw link, rate {args.rate:.0f} Hz, {args.duration:.0f} s, "
          f"curve {'on' if args.curve else 'off'}")
    print(f"sent {log.sent}, send refused {log.send_failed}, echoed {got}, "
          f"lost {log.sent + log.send_failed - got}")
    print_latency(log, load_before)
    return 0


if __name__ == "__main__":
    sys.exit(main())
