"""The friction-gain staircase (Jiao 2018 IV-C, ``fydpad texture staircase``) as a web
session: the same :class:`~fydpad.texture.staircase.Staircase`, the same log
(``trial,b,answer,reversal``, one row per answer, fsync'ed) replayed to resume, one log
per participant in ``RESULTS/staircase/PARTICIPANT.csv``.

``present(b)`` is called with the b of each trial (and the result when done), so the
station applies it live to the friction model it renders.
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Callable
from pathlib import Path

from fydpad.errors import UserError
from fydpad.texture.staircase import ANSWERS, LOG_COLUMNS, Staircase, replay_log
from fydpad.web.experiment import ExperimentError, check_participant, drop_torn_line


class StaircaseSession:
    """One participant's staircase: answer, resume, result."""

    def __init__(self, log_path: Path, stairs: Staircase,
                 present: Callable[[float], None] | None = None):
        self.log_path = log_path
        self.stairs = stairs
        self.present = present
        self.history: list[dict] = []

    @classmethod
    def open(cls, results_dir: str | Path, participant: str, start: float = 400.0,
             step: float = 10.0, present: Callable[[float], None] | None = None
             ) -> StaircaseSession:
        """Start a participant's staircase, or resume it from its log."""
        check_participant(participant)
        log_path = Path(results_dir) / "staircase" / f"{participant}.csv"
        log_path.parent.mkdir(parents=True, exist_ok=True)
        return cls.from_log(log_path, start, step, present)

    @classmethod
    def from_log(cls, log_path: str | Path, start: float = 400.0, step: float = 10.0,
                 present: Callable[[float], None] | None = None) -> StaircaseSession:
        """A staircase logged to ``log_path`` (``fydpad texture staircase --log``, or a
        participant's in the web view), resumed from it when it exists."""
        if not step > 0:
            raise ExperimentError(f"step must be positive, got {step:g}")
        log_path = Path(log_path)
        try:
            drop_torn_line(log_path, LOG_COLUMNS)
        except OSError as exc:
            raise ExperimentError(f"{log_path}: cannot be written ({exc.strerror})") from None
        stairs = Staircase(start=start, step=step)
        try:
            replay_log(log_path, stairs)
        except UserError as exc:
            raise ExperimentError(str(exc)) from None
        session = cls(log_path, stairs, present)
        session.history = _read_rows(log_path)
        session._present()
        return session

    @property
    def participant(self) -> str:
        return self.log_path.stem

    def _append(self, row) -> None:
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerow(row)
        with self.log_path.open("a", encoding="utf-8", newline="") as fh:
            fh.write(buf.getvalue())
            fh.flush()
            os.fsync(fh.fileno())

    def _present(self) -> None:
        if self.present is not None:
            s = self.stairs
            self.present(s.result if s.done else s.b)

    def answer(self, rougher: str, trial: int | None = None) -> bool:
        """Which felt rougher, 'real' or 'virtual'; logged before b moves. ``trial`` (the
        trial the page showed) guards against a double submission."""
        s = self.stairs
        if s.done:
            raise ExperimentError("the staircase is complete")
        if trial is not None and int(trial) != s.trials + 1:
            raise ExperimentError(f"answer for trial {trial}, but the current trial is "
                                  f"{s.trials + 1}")
        b = s.b
        try:
            reversal = s.answer(rougher)
        except ValueError as exc:
            raise ExperimentError(str(exc)) from None
        row = (s.trials, f"{b:g}", ANSWERS[rougher.strip().lower()], int(reversal))
        self._append(row)
        self.history.append(dict(zip(LOG_COLUMNS, (str(v) for v in row), strict=True)))
        self._present()
        return reversal

    def status(self) -> dict:
        s = self.stairs
        return {"participant": self.participant, "trial": s.trials + 1, "b": s.b,
                "start": s.start, "step": s.step, "reversals": list(s.reversals),
                "needed_reversals": s.skip_reversals + s.use_reversals, "done": s.done,
                "result": s.result if s.done else None, "log": str(self.log_path),
                "history": self.history}


def _read_rows(path: Path) -> list[dict]:
    with path.open(newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))

