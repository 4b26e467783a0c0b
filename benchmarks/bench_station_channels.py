"""What ``fydpad run --channel`` costs the 1 kHz render loop.

1. In process: the time of ``ChannelOutputs.tick`` per tick (the store, and every 10th tick
   the block's render and hand-off) for a friction model's vibration term to a WAV file,
   its 48 kHz electrostatic channel to a WAV file, and both; with the family's own tick for
   scale.
2. The station: ``fydpad run --replay REC --motors sim --texture friction`` with and
   without those channels, alternated, the render loop's on-time % from ``--stats``.

    nice python benchmarks/bench_station_channels.py [REPS]
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def friction_model(path: Path) -> Path:
    path.write_text(json.dumps({
        "format": "fydpad-texture-model", "kind": "friction", "format_version": 1,
        "mu": list(0.5 + 0.2 * np.sin(np.linspace(0, 2 * np.pi, 200, endpoint=False))),
        "dx_mm": 0.05, "x0_mm": 0.0}, allow_nan=False))
    return path


def per_tick(model_path: Path, tmp: Path, n: int = 20000) -> None:
    from fydpad.station.chains import _TickModel
    from fydpad.station.outputs import ChannelOutputs

    model = _TickModel(str(model_path), 1000.0)
    cases = {"family tick only": [], "vibration -> wav": [f"wav:{tmp / 'v.wav'}"],
             "audio 48 kHz -> wav": [f"audio=wav:{tmp / 'V.wav'},fs=500"],
             "both": [f"wav:{tmp / 'v2.wav'}", f"audio=wav:{tmp / 'V2.wav'},fs=500"]}
    for name, specs in cases.items():
        out = ChannelOutputs(specs, [model], 1000.0, 10) if specs else None
        dt = np.empty(n)
        for k in range(n):
            t = k / 1000.0
            x = 20.0 * math.cos(t)  # a new centroid every 33 ms, as the camera gives
            x = round(x * 30) / 30
            t0 = time.perf_counter_ns()
            vals = model.family.tick(t, True, x, 0.0, 20.0, 0.5)
            if out is not None:
                out.tick(t, True, x, 0.0, 20.0, 0.5, 1.0, 0, vals, vals[0])
            dt[k] = (time.perf_counter_ns() - t0) / 1000.0
        if out is not None:
            out.close()
        flush = dt[9::10]
        print(f"{name:22s} per tick median {np.median(dt):6.1f} us  p99 "
              f"{np.percentile(dt, 99):6.1f} us  max {dt.max():7.1f} us;  "
              f"flush ticks median {np.median(flush):6.1f} us")


def station(rec: Path, model_path: Path, tmp: Path, reps: int) -> None:
    base = [sys.executable, "-m", "fydpad.cli", "run", "--replay", str(rec), "--motors", "sim",
            "--texture", str(model_path), "--no-realtime"]
    chans = ["--channel", f"wav:{tmp / 'sv.wav'}", "--channel",
             f"audio=wav:{tmp / 'sV.wav'},fs=500"]
    got: dict[str, list[float]] = {"without": [], "with": []}
    for _ in range(reps):
        for name, extra in (("without", []), ("with", chans)):
            st = tmp / "st.json"
            subprocess.run([*base, *extra, "--stats", str(st)], check=True, cwd=ROOT,
                           capture_output=True)
            got[name].append(json.loads(st.read_text())["render"]["on_time_pct"])
    for name, v in got.items():
        print(f"station {name:7s} channels: on time {' '.join(f'{p:.2f}' for p in v)} % "
              f"(median {np.median(v):.2f} %)")


def main() -> None:
    reps = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    from tests.conftest import write_blob_recording

    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        model = friction_model(tmp / "friction.json")
        per_tick(model, tmp)
        pos = [None] * 6 + [(20 * np.cos(k / 8), 15 * np.sin(k / 8)) for k in range(120)]
        write_blob_recording(tmp / "rec", pos + [None] * 6)
        station(tmp / "rec", model, tmp, reps)


if __name__ == "__main__":
    main()
