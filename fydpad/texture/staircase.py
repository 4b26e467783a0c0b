"""The 1-up/1-down staircase that sets the voltage factor b with a user (001 IV-C).

Start at b = 400, step 10. Each trial the user says which felt rougher: the real
sample (b goes up by a step) or the virtual one (b goes down). A reversal is a change
of direction. The result is the mean b at the four reversals after the first two
(001: "after the first two reversals, the average value from the next four reversals").

Pure state: ``Staircase.answer`` returns the next b; the command logs each answer as it
comes (``trial,b,answer,reversal``) and replays the log to resume.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

from fydpad.errors import UserError

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
