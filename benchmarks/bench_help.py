"""How fast ``fydpad --help`` and each ``fydpad COMMAND --help`` start, run on demand:
``python benchmarks/bench_help.py [--runs N]``.

Target: under 0.3 s each. Baseline, measured in the same run: a bare interpreter that
only parses arguments (``python -c "import argparse"``), the floor no command can beat.
For each command it prints the median wall time of N fresh processes, the time above
that floor, and, from ``python -X importtime``, the three slowest top-level imports
(cumulative), so a slow --help names what to make lazy.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fydpad.cli import COMMANDS  # noqa: E402  (after the path above)

ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def wall_s(argv: list[str], runs: int) -> float:
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run(argv, env=ENV, cwd=ROOT, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL, check=False)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def slowest_imports(args: list[str], n: int = 3) -> list[tuple[str, float]]:
    r = subprocess.run([sys.executable, "-X", "importtime", "-m", "fydpad.cli", *args],
                       env=ENV, cwd=ROOT, capture_output=True, text=True, check=False)
    rows = []
    for line in r.stderr.splitlines():
        if not line.startswith("import time:") or "cumulative" in line:
            continue
        _, _, cum, name = (p.strip() for p in line.replace("import time:", "|").split("|"))
        if not line.split("|")[2].startswith("  ") and name not in ("site", "encodings"):
            rows.append((name, int(cum) / 1e6))
    return sorted(rows, key=lambda r: -r[1])[:n]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5, help="processes per command (median)")
    runs = ap.parse_args().runs
    floor = wall_s([sys.executable, "-c", "import argparse"], runs)
    print(f"baseline (python -c 'import argparse'): {floor * 1e3:.0f} ms (median of {runs})")
    print(f"{'command':<24}{'wall ms':>9}{'above':>8}{'ratio':>7}  slowest imports (ms)")
    for cmd in ["", *COMMANDS]:
        args = [*cmd.split(), "--help"]
        t = wall_s([sys.executable, "-m", "fydpad.cli", *args], runs)
        slow = ", ".join(f"{n} {s * 1e3:.0f}" for n, s in slowest_imports(args))
        label = f"fydpad {cmd} --help".replace("  ", " ")
        print(f"{label:<24}{t * 1e3:9.0f}{(t - floor) * 1e3:8.0f}{t / floor:7.2f}  {slow}")


if __name__ == "__main__":
    main()
