"""A master process for the fault tests: streams a 40 mm/s circle to argv[1] for argv[2] s."""

from __future__ import annotations

import sys

from teleop.link import MasterSocket
from teleop.master import stream
from teleop.trajectories import circle, finger_stream

if __name__ == "__main__":
    states, _ = finger_stream(circle(), float(sys.argv[2]))
    with MasterSocket(sys.argv[1]) as sock:
        print("streaming", flush=True)
        log = stream(states, sock, preroll_s=0.0)
        print(f"sent {log.sent} failed {log.send_failed}", flush=True)
