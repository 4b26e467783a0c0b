"""The operator hold from the terminal: ``h`` or the space bar toggles it.

Only when standard input is a terminal: it is put in cbreak mode (keys arrive one by one,
unechoed; Ctrl-C still interrupts) for the run and restored after, whatever happens.
"""

from __future__ import annotations

import os
import select
import sys
import termios
import threading
import tty
from collections.abc import Callable
from types import TracebackType

#: Keys that toggle the hold.
HOLD_KEYS = (b"h", b"H", b" ")


class HoldKeys:
    """``with HoldKeys(toggle):`` calls ``toggle()`` on each hold key typed."""

    def __init__(self, toggle: Callable[[], object], stdin=None) -> None:
        self.toggle = toggle
        self.stdin = stdin if stdin is not None else sys.stdin
        self.active = False
        self._saved = None
        self._thread: threading.Thread | None = None
        self._stop_r = self._stop_w = -1

    def __enter__(self) -> HoldKeys:
        try:
            fd = self.stdin.fileno()
        except (AttributeError, ValueError, OSError):
            return self
        if not os.isatty(fd):
            return self
        self._fd = fd
        self._saved = termios.tcgetattr(fd)
        tty.setcbreak(fd)
        self._stop_r, self._stop_w = os.pipe()
        self._thread = threading.Thread(target=self._run, name="hold-keys", daemon=True)
        self._thread.start()
        self.active = True
        return self

    def _run(self) -> None:
        while True:
            ready, _, _ = select.select([self._fd, self._stop_r], [], [])
            if self._stop_r in ready:
                return
            try:
                key = os.read(self._fd, 1)
            except OSError:
                return
            if not key:
                return
            if key in HOLD_KEYS:
                self.toggle()

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if self._thread is not None:
            os.write(self._stop_w, b"x")
            self._thread.join(timeout=2.0)
            os.close(self._stop_r)
            os.close(self._stop_w)
        if self._saved is not None:
            termios.tcsetattr(self._fd, termios.TCSADRAIN, self._saved)
