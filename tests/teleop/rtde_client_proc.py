"""Subprocess for test_rtde_wire: the real ur-rtde RTDEReceiveInterface reads poses."""

from __future__ import annotations

import json
import sys
import time

import rtde_receive

if __name__ == "__main__":
    r = rtde_receive.RTDEReceiveInterface(sys.argv[1], 500.0)
    poses = []
    for _ in range(5):
        poses.append(r.getActualTCPPose())
        time.sleep(0.05)
    print(json.dumps({"poses": poses, "connected": r.isConnected(),
                      "pstop": r.isProtectiveStopped()}), flush=True)
    r.disconnect()
