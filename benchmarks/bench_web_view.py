"""The web view never slows the render loop: the station replays a recording
for 15 s with ``--web`` and ``--stats`` three times: no browser; 4 clients fetching the
state and the image as fast as they can; 50 stalled clients that ask for images and never
read them. Prints the render loop's figures from ``--stats`` for each.

Run: ``python benchmarks/bench_web_view.py``."""
import json
import math
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from tests.conftest import write_blob_recording

d = Path(tempfile.mkdtemp(prefix="bench_web_"))
write_blob_recording(d / "rec", [(30 * math.cos(k / 14), 20 * math.sin(k / 14))
                                 for k in range(30 * 25)], fps=30.0)


def hammer(op, port: int, stop: threading.Event) -> None:
    while not stop.is_set():
        try:
            op.open(f"http://127.0.0.1:{port}/api/state?since=0", timeout=5).read()
            op.open(f"http://127.0.0.1:{port}/api/frame.jpg", timeout=5).read()
        except OSError:
            pass


def run(mode: str, port: int) -> None:
    p = subprocess.Popen([sys.executable, "-m", "fydpad.cli", "run", "--replay", str(d / "rec"),
                          "--web", f"127.0.0.1:{port}", "--duration", "15",
                          "--stats", str(d / f"{mode}.json"), "--web-results", str(d / "res")],
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=d)
    time.sleep(4)
    stop = threading.Event()
    socks = []
    op = urllib.request.build_opener(urllib.request.ProxyHandler({}))
    if mode == "hammer":
        for _ in range(4):
            threading.Thread(target=hammer, args=(op, port, stop), daemon=True).start()
    if mode == "stalled":
        for _ in range(50):  # ask for images and never read them
            s = socket.create_connection(("127.0.0.1", port))
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1024)
            s.sendall(b"GET /api/frame.jpg HTTP/1.1\r\nHost: x\r\n\r\n" * 20)
            socks.append(s)
    p.wait(timeout=60)
    stop.set()
    st = json.loads((d / f"{mode}.json").read_text())["render"]
    print(f"{mode:8s} render {st['rate_hz']:.1f} Hz, {st['on_time_pct']:.2f} % on time, "
          f"jitter p99 {st['jitter_ms']['p99']:.3f} ms, scheduling {st.get('scheduling')}")


for i, m in enumerate(["none", "hammer", "stalled"]):
    run(m, 8790 + i)
