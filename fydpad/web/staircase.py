"""The 1-up/1-down staircase that sets the electrostatic factor b with a user (Jiao
2018 IV-C), for ``fydpad texture staircase`` and the web experiment.

Start at b = 400, step 10. Each trial the user says which felt rougher: the real
sample (b goes up by a step) or the virtual one (b goes down). A reversal is a change
of direction. The result is the mean b at the four reversals after the first two
("after the first two reversals, the average value from the next four reversals").
:class:`Staircase` is pure state; a :class:`StaircaseSession` logs each answer as it
comes (``trial,b,answer,reversal``, fsync'ed) and replays the log to resume, one log
per participant in ``RESULTS/staircase/PARTICIPANT.csv`` on the web.

``present(b)`` is called with the b of each trial (and the result when done), so the
station applies it live to the friction model it renders.
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from fydpad.errors import UserError
from fydpad.web.experiment import ExperimentError, check_participant, drop_torn_line

ANSWERS = {"r": "real", "real": "real", "v": "virtual", "virtual": "virtual"}
LOG_COLUMNS = ("trial", "b", "answer", "reversal")


@dataclass
class Staircase:
    start: float = 400.0
    step: float = 10.0
    skip_reversals: int = 2
    use_reversals: int = 4
    b: float = field(init=False)
    trials: int = field(init=False, default=0)
    reversals: list[float] = field(init=False, default_factory=list)
    _last_dir: int = field(init=False, default=0)

    def __post_init__(self) -> None:
        if not self.step > 0:
            raise ValueError("step must be positive")
        self.b = float(self.start)

    @property
    def done(self) -> bool:
        return len(self.reversals) >= self.skip_reversals + self.use_reversals

    @property
    def result(self) -> float:
        """Mean b at reversals 3..6 (NaN until done)."""
        if not self.done:
            return float("nan")
        used = self.reversals[self.skip_reversals:self.skip_reversals + self.use_reversals]
        return sum(used) / len(used)

    def answer(self, rougher: str) -> bool:
        """Record which felt rougher ('real'/'virtual'); True if this was a reversal."""
        which = ANSWERS.get(rougher.strip().lower())
        if which is None:
            raise ValueError(f"answer must be real/r or virtual/v, got {rougher!r}")
        direction = 1 if which == "real" else -1  # real rougher: more voltage
        reversal = self._last_dir != 0 and direction != self._last_dir
        if reversal:
            self.reversals.append(self.b)
        self._last_dir = direction
        self.trials += 1
        self.b = max(self.b + direction * self.step, 0.0)
        return reversal


def replay_log(path: str | Path, stairs: Staircase) -> int:
    """Feed a staircase the answers of an existing log; the number of trials read."""
    path = Path(path)
    if not path.exists():
        return 0
    with path.open(newline="", encoding="utf-8") as fh:
        rows = [r for r in csv.reader(fh) if r and not r[0].startswith("#")]
    if not rows:
        return 0
    if tuple(h.strip() for h in rows[0]) != LOG_COLUMNS:
        raise UserError(f"{path}: line 1: header must be {','.join(LOG_COLUMNS)}")
    for i, r in enumerate(rows[1:], start=2):
        try:
            b = float(r[1])
            if abs(b - stairs.b) > 1e-9:
                raise UserError(f"{path}: line {i}: column 'b' is {b:g}, the staircase is at "
                                f"{stairs.b:g} (was the log written with other --start/--step?)")
            stairs.answer(r[2])
        except (IndexError, ValueError) as exc:
            raise UserError(f"{path}: line {i}: column 'answer': {exc}") from None
    return len(rows) - 1



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

