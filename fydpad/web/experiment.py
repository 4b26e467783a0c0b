"""The paper's absolute identification task (section IV-C, Table I), as pure logic.

N rendered specimens (softness x texture) are each presented K times in a random order
per participant (seeded, the seed logged); the participant names the physical specimen
each rendered one feels like. Answers go to one CSV per participant, written and
fsync'ed answer by answer, so a session resumes after an interruption without losing
any. The confusion matrix, the relative accuracy per specimen and the average against
chance make the report (a table and a PNG plot). The layout is in docs/experiment.md.

Nothing here touches the station: presenting a stimulus is a callback (see
:class:`StationStimulus` in :mod:`fydpad.web.server` for the station's).
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import os
import re
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from vision.errors import UserError
from vision.strict_json import finite

#: CSV columns, one row per answer (docs/experiment.md).
CSV_FIELDS = ("participant", "trial", "presented", "answer", "correct", "seed", "time_utc")


@dataclass(frozen=True)
class Stimulus:
    """One rendered specimen: a softness and a texture."""

    name: str
    stiffness_n_per_mm: float
    #: Grating period of the texture (mm); the texture model renders it.
    grating_mm: float
    description: str = ""
    #: The texture model the station renders (``[KIND:]MODEL.json``); None: softness only.
    texture: str | None = None


#: The paper's four specimens (section IV-A): S1 = 0.88 N/mm, S2 = 0.39 N/mm; R1 = 3.90 mm,
#: R2 = 2.15 mm gratings. SS1 = (S1, R1), SS2 = (S1, R2), SS3 = (S2, R1), SS4 = (S2, R2).
PAPER_STIMULI: tuple[Stimulus, ...] = (
    Stimulus("SS1", 0.88, 3.90, "S1 softness, R1 roughness"),
    Stimulus("SS2", 0.88, 2.15, "S1 softness, R2 roughness"),
    Stimulus("SS3", 0.39, 3.90, "S2 softness, R1 roughness"),
    Stimulus("SS4", 0.39, 2.15, "S2 softness, R2 roughness"),
)
PAPER_REPEATS = 3

_PARTICIPANT_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


class ExperimentError(UserError, ValueError):
    """A bad experiment setting, answer or results file."""


def check_participant(participant: str) -> str:
    if not _PARTICIPANT_RE.match(participant or ""):
        raise ExperimentError(
            f"participant id {participant!r}: use 1-64 letters, digits, '_', '-' or '.'")
    return participant


def participant_seed(participant: str, base_seed: int = 0) -> int:
    """A reproducible seed per participant (logged with every answer)."""
    digest = hashlib.sha256(f"{base_seed}:{participant}".encode()).digest()
    return int.from_bytes(digest[:4], "big")


def presentation_order(names: Sequence[str], repeats: int, seed: int) -> list[str]:
    """Each name exactly ``repeats`` times, in a random order drawn from ``seed``."""
    if repeats < 1:
        raise ExperimentError(f"repeats must be at least 1, got {repeats}")
    if len(names) < 2 or len(set(names)) != len(names):
        raise ExperimentError(f"need at least two distinct specimens, got {list(names)}")
    trials = [n for n in names for _ in range(repeats)]
    rng = np.random.default_rng(seed)
    return [trials[i] for i in rng.permutation(len(trials))]


# -- results ----------------------------------------------------------------------


@dataclass
class Confusion:
    """Counts of answers (columns) per presented specimen (rows), like Table I."""

    names: list[str]
    counts: np.ndarray  # int, [presented, answer]

    @property
    def per_specimen_accuracy(self) -> np.ndarray:
        """Relative accuracy per presented specimen (correct / presented), NaN if never."""
        rows = self.counts.sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(rows > 0, np.diag(self.counts) / np.maximum(rows, 1), np.nan)

    @property
    def total(self) -> int:
        return int(self.counts.sum())

    @property
    def accuracy(self) -> float:
        """Correct answers over all answers (with balanced presentations: the mean of
        the per-specimen accuracies)."""
        return float(np.trace(self.counts) / self.total) if self.total else float("nan")

    @property
    def mean_specimen_accuracy(self) -> float:
        acc = self.per_specimen_accuracy
        return float(np.nanmean(acc)) if np.isfinite(acc).any() else float("nan")

    @property
    def chance(self) -> float:
        return 1.0 / len(self.names)

    def as_dict(self) -> dict:
        return {
            "names": list(self.names),
            "counts": self.counts.tolist(),
            "per_specimen_accuracy": [None if not np.isfinite(a) else float(a)
                                      for a in self.per_specimen_accuracy],
            "accuracy": None if not self.total else self.accuracy,
            "mean_specimen_accuracy": None if not self.total else self.mean_specimen_accuracy,
            "chance": self.chance,
            "answers": self.total,
        }

    def table(self) -> str:
        """A plain-text table like the paper's Table I."""
        w = max(6, *(len(n) + 2 for n in self.names))
        head = "".ljust(w) + "".join(n.rjust(w) for n in self.names) + "  Relative accuracy"
        lines = [head]
        for i, n in enumerate(self.names):
            acc = self.per_specimen_accuracy[i]
            acc_s = "-" if not np.isfinite(acc) else f"{100 * acc:.1f} %"
            lines.append(n.ljust(w) + "".join(str(int(c)).rjust(w) for c in self.counts[i])
                         + f"  {acc_s}")
        if self.total:
            lines.append(f"average {100 * self.accuracy:.1f} % ({np.trace(self.counts)} of "
                         f"{self.total} correct), chance {100 * self.chance:.1f} %")
        return "\n".join(lines)


def confusion(pairs: Sequence[tuple[str, str]], names: Sequence[str]) -> Confusion:
    """The confusion matrix of (presented, answer) pairs over ``names``."""
    index = {n: i for i, n in enumerate(names)}
    counts = np.zeros((len(names), len(names)), dtype=int)
    for presented, answer in pairs:
        if presented not in index or answer not in index:
            raise ExperimentError(f"unknown specimen in ({presented!r}, {answer!r}); "
                                  f"known: {list(names)}")
        counts[index[presented], index[answer]] += 1
    return Confusion(list(names), counts)


def plot_confusion(conf: Confusion, path_or_buffer, title: str = "") -> None:
    """The confusion matrix as a PNG (matplotlib Agg): counts, accuracy per row, chance."""
    # lazy: matplotlib costs the web view's start-up; only a finished experiment draws
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure  # after the backend is chosen

    fig = Figure(figsize=(6.4, 4.2), dpi=100)
    ax = fig.add_subplot(1, 1, 1)
    n = len(conf.names)
    ax.imshow(conf.counts, cmap="Blues", vmin=0, vmax=max(1, conf.counts.max()))
    for i in range(n):
        for j in range(n):
            c = int(conf.counts[i, j])
            ax.text(j, i, str(c), ha="center", va="center",
                    color="white" if c > conf.counts.max() / 2 else "black", fontsize=12)
    ax.set_xticks(range(n), conf.names)
    acc = conf.per_specimen_accuracy
    ylabels = [f"{nm} ({'-' if not np.isfinite(a) else f'{100 * a:.1f} %'})"
               for nm, a in zip(conf.names, acc, strict=True)]
    ax.set_yticks(range(n), ylabels)
    ax.set_xlabel("answer (physical specimen)")
    ax.set_ylabel("rendered specimen (relative accuracy)")
    avg = "-" if not conf.total else f"{100 * conf.accuracy:.1f} %"
    ax.set_title(title or f"average {avg}, chance {100 * conf.chance:.1f} % "
                          f"({conf.total} answers)")
    fig.tight_layout()
    fig.savefig(path_or_buffer, format="png")


def plot_png(conf: Confusion, title: str = "") -> bytes:
    buf = io.BytesIO()
    plot_confusion(conf, buf, title)
    return buf.getvalue()


# -- one participant's session ----------------------------------------------------------


@dataclass
class SessionPlan:
    """What a participant's session presents (``PARTICIPANT.json`` next to the CSV)."""

    participant: str
    seed: int
    repeats: int
    stimuli: list[Stimulus]
    order: list[str]
    created_utc: str = ""

    def to_json(self) -> str:
        d = asdict(self)
        d["format"] = "fydpad-experiment-1"
        return json.dumps(finite(d), indent=2, allow_nan=False) + "\n"

    @classmethod
    def from_json(cls, text: str, where: str) -> SessionPlan:
        try:
            d = json.loads(text)
            d.pop("format", None)
            d["stimuli"] = [Stimulus(**s) for s in d["stimuli"]]
            plan = cls(**d)
        except (ValueError, TypeError, KeyError) as exc:
            raise ExperimentError(f"{where}: not a session plan ({exc})") from None
        expected = presentation_order([s.name for s in plan.stimuli], plan.repeats, plan.seed)
        if expected != plan.order:
            raise ExperimentError(f"{where}: the order does not follow from its seed")
        return plan


def _utc_now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())


def _fsync_write(path: Path, text: str, mode: str = "a") -> None:
    with path.open(mode, encoding="utf-8", newline="") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())


def read_answers(csv_path: Path) -> list[dict]:
    """The complete answer rows of a results CSV (a torn last line is ignored)."""
    if not csv_path.exists():
        return []
    text = csv_path.read_text(encoding="utf-8")
    if text and not text.endswith("\n"):
        text = text[: text.rfind("\n") + 1]  # an answer cut short by a crash
    rows = list(csv.DictReader(io.StringIO(text)))
    for k, row in enumerate(rows, start=1):
        if set(row) != set(CSV_FIELDS) or None in row.values():
            raise ExperimentError(f"{csv_path}: line {k + 1}: expected columns "
                                  f"{','.join(CSV_FIELDS)}")
        if int(row["trial"]) != k:
            raise ExperimentError(f"{csv_path}: line {k + 1}: trial {row['trial']}, "
                                  f"expected {k}")
    return rows


def drop_torn_line(csv_path: Path, header: Sequence[str] = CSV_FIELDS) -> None:
    """Cut an answer a crash left half-written, so the next answer starts a clean line;
    a missing file is created with its ``header``."""
    if not csv_path.exists():
        _fsync_write(csv_path, ",".join(header) + "\n", "w")
        return
    data = csv_path.read_bytes()
    if data and not data.endswith(b"\n"):
        with csv_path.open("r+b") as fh:
            fh.truncate(data.rfind(b"\n") + 1)
            fh.flush()
            os.fsync(fh.fileno())


@dataclass
class ExperimentSession:
    """A participant's session: the plan, the answers so far, the next trial.

    ``present`` is called with each stimulus when it becomes the current one (at start,
    on resume and after each answer), so the station renders what the page shows.
    """

    results_dir: Path
    plan: SessionPlan
    answers: list[dict] = field(default_factory=list)
    present: Callable[[Stimulus | None], None] | None = None

    @classmethod
    def open(
        cls,
        results_dir: str | Path,
        participant: str,
        stimuli: Sequence[Stimulus] = PAPER_STIMULI,
        repeats: int = PAPER_REPEATS,
        seed: int | None = None,
        present: Callable[[Stimulus | None], None] | None = None,
    ) -> ExperimentSession:
        """Start a participant's session, or resume it if its files exist."""
        check_participant(participant)
        results_dir = Path(results_dir)
        if not results_dir.is_dir():  # made by the first result, and said so
            results_dir.mkdir(parents=True, exist_ok=True)
            print(f"experiment results: {results_dir.resolve()}", file=sys.stderr, flush=True)
        plan_path = results_dir / f"{participant}.json"
        csv_path = results_dir / f"{participant}.csv"
        if plan_path.exists():
            plan = SessionPlan.from_json(plan_path.read_text(encoding="utf-8"), str(plan_path))
            answers = read_answers(csv_path)
            drop_torn_line(csv_path)
            for row in answers:
                k = int(row["trial"])
                if row["presented"] != plan.order[k - 1]:
                    raise ExperimentError(f"{csv_path}: trial {k} presented "
                                          f"{row['presented']}, the plan says "
                                          f"{plan.order[k - 1]}")
            session = cls(results_dir, plan, answers, present)
        else:
            seed = participant_seed(participant) if seed is None else int(seed)
            names = [s.name for s in stimuli]
            plan = SessionPlan(participant, seed, int(repeats), list(stimuli),
                               presentation_order(names, repeats, seed), _utc_now())
            _fsync_write(plan_path, plan.to_json(), "w")
            _fsync_write(csv_path, ",".join(CSV_FIELDS) + "\n", "w")
            session = cls(results_dir, plan, [], present)
        session._present_current()
        return session

    @property
    def csv_path(self) -> Path:
        return self.results_dir / f"{self.plan.participant}.csv"

    @property
    def names(self) -> list[str]:
        return [s.name for s in self.plan.stimuli]

    @property
    def trial(self) -> int:
        """The 1-based number of the current trial (total + 1 when done)."""
        return len(self.answers) + 1

    @property
    def total(self) -> int:
        return len(self.plan.order)

    @property
    def done(self) -> bool:
        return len(self.answers) >= self.total

    def current(self) -> Stimulus | None:
        if self.done:
            return None
        name = self.plan.order[len(self.answers)]
        return next(s for s in self.plan.stimuli if s.name == name)

    def _present_current(self) -> None:
        if self.present is not None:
            self.present(self.current())

    def answer(self, answer: str, trial: int | None = None) -> dict:
        """Record the participant's answer to the current trial (fsync'ed), advance.

        ``trial`` (the trial the experimenter saw) guards against a double submission.
        """
        if self.done:
            raise ExperimentError("the session is complete")
        if answer not in self.names:
            raise ExperimentError(f"unknown answer {answer!r}; one of {self.names}")
        if trial is not None and int(trial) != self.trial:
            raise ExperimentError(f"answer for trial {trial}, but the current trial is "
                                  f"{self.trial}")
        presented = self.current().name
        row = {"participant": self.plan.participant, "trial": str(self.trial),
               "presented": presented, "answer": answer,
               "correct": "1" if answer == presented else "0",
               "seed": str(self.plan.seed), "time_utc": _utc_now()}
        buf = io.StringIO()
        csv.DictWriter(buf, CSV_FIELDS, lineterminator="\n").writerow(row)
        _fsync_write(self.csv_path, buf.getvalue())
        self.answers.append(row)
        self._present_current()
        return row

    def confusion(self) -> Confusion:
        return confusion([(r["presented"], r["answer"]) for r in self.answers], self.names)

    def status(self) -> dict:
        cur = self.current()
        return {
            "participant": self.plan.participant, "seed": self.plan.seed,
            "repeats": self.plan.repeats, "trial": self.trial, "total": self.total,
            "done": self.done, "names": self.names,
            "stimuli": [asdict(s) for s in self.plan.stimuli],
            "current": asdict(cur) if cur is not None else None,
            "csv": str(self.csv_path),
            "confusion": self.confusion().as_dict(),
        }


# -- reports over a results directory ------------------------------------------------------


def load_results(results_dir: str | Path) -> tuple[list[str], list[dict], list[str]]:
    """(specimen names, all answer rows, participants) of every session in a directory."""
    results_dir = Path(results_dir)
    if not results_dir.is_dir():
        raise ExperimentError(f"{results_dir}: no such results directory")
    names: list[str] | None = None
    rows: list[dict] = []
    participants = []
    for plan_path in sorted(results_dir.glob("*.json")):
        plan = SessionPlan.from_json(plan_path.read_text(encoding="utf-8"), str(plan_path))
        plan_names = [s.name for s in plan.stimuli]
        if names is None:
            names = plan_names
        elif plan_names != names:
            raise ExperimentError(f"{plan_path}: specimens {plan_names} differ from the "
                                  f"other sessions' {names}")
        rows += read_answers(plan_path.with_suffix(".csv"))
        participants.append(plan.participant)
    if names is None:
        raise ExperimentError(f"{results_dir}: no sessions (PARTICIPANT.json files)")
    return names, rows, participants


def report(results_dir: str | Path) -> tuple[Confusion, list[str]]:
    names, rows, participants = load_results(results_dir)
    return confusion([(r["presented"], r["answer"]) for r in rows], names), participants
