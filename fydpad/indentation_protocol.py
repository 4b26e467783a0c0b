"""The indentation calibration protocol: the presses a user records so that
``fydpad calibrate indentation`` can fit the correction beyond the plane for a new
fabric (docs/indentation.md), in about two minutes.

Three recordings of 39 s: 3 s with the fabric clear (the sensors' rest distances),
then 12 presses, each about 3 s (down in under a second, hold 1.5 s at the target
depth, lift clear and move to the next mark: the pace of the synthetic hand,
``fydpad.synth.trajectory.protocol``, at a finger's 80 mm/s). The marks form a
4 x 3 grid over 80 % of the workspace, shifted by a third of a cell in each recording
so that the 36 presses cover it, edges included; the depths, 4 to 35 mm, rotate along
the rows so that every part of the workspace is seen shallow and deep. The true depth
comes from an indenter (its stage travel past the first touch) or from a finger on the
load cell (depth = force / stiffness, the stiffness measured with a depth gauge first).

Pure data; ``protocol_text`` is what ``fydpad calibrate indentation --protocol`` prints
and the web view's guide shows step by step.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass

#: Target depths in mm, rotating along each row (slides are 2-20 mm deep, taps deeper).
DEPTHS_MM = (4.0, 10.0, 20.0, 35.0)
RECORDINGS = 3
CLEAR_S = 3.0
PRESS_S = 3.0
HOLD_S = 1.5
GRID = (4, 3)


@dataclass(frozen=True)
class Press:
    """One press of the protocol: where (workspace mm) and how deep."""

    recording: int
    number: int
    x_mm: float
    y_mm: float
    depth_mm: float


def presses(workspace_mm: tuple[float, float] = (100.0, 70.0)) -> list[Press]:
    """Every press of the protocol, recording by recording, far row first."""
    cols, rows = GRID
    w, h = 0.8 * workspace_mm[0], 0.8 * workspace_mm[1]
    cell_w, cell_h = w / cols, h / rows
    out = []
    for r in range(RECORDINGS):
        shift = (r / RECORDINGS - 1.0 / 3.0)  # -1/3, 0, +1/3 of a cell
        k = 0
        for j in range(rows):
            for i in range(cols):
                x = -w / 2 + (i + 0.5 + shift) * cell_w
                y = h / 2 - (j + 0.5 - shift) * cell_h
                depth = DEPTHS_MM[(i + j + r) % len(DEPTHS_MM)]
                out.append(Press(r + 1, k + 1, round(x, 1), round(y, 1), depth))
                k += 1
    return out


def duration_s() -> float:
    cols, rows = GRID
    return RECORDINGS * (CLEAR_S + cols * rows * PRESS_S)


@dataclass(frozen=True)
class Step:
    title: str
    text: str
    #: The presses of a recording step, in order.
    presses: tuple[Press, ...] = ()


def steps(workspace_mm: tuple[float, float] = (100.0, 70.0)) -> list[Step]:
    """The protocol as steps a user follows in order."""
    cols, rows = GRID
    out = [
        Step("Prepare",
             "Motors at rest (the fabric's softest setting, as in use). Mark the press "
             "points on the fabric's top with a washable pen, or use the web view's "
             "guide, which shows them. Either an indenter: a round tip of about 16 mm "
             "on a vertical stage with a depth scale; or your finger with the load cell "
             "under the pad and a depth gauge (a caliper's depth rod) at hand."),
        Step("Finger only: measure the stiffness",
             "Press the centre to 10 mm and to 30 mm on the depth gauge, hold each 2 s, "
             "and note the load cell's force: the stiffness k = force / depth (N/mm). "
             "During the presses below the true depth is then force / k."),
    ]
    by_rec: dict[int, list[Press]] = {}
    for p in presses(workspace_mm):
        by_rec.setdefault(p.recording, []).append(p)
    for r, ps in by_rec.items():
        out.append(Step(
            f"Recording {r} of {RECORDINGS} ({CLEAR_S + len(ps) * PRESS_S:.0f} s)",
            f"Start recording (fydpad run --record cal{r}). Keep the fabric clear for "
            f"{CLEAR_S:.0f} s (the sensors' rest distances). Then press the {len(ps)} "
            f"points in order ({rows} rows of {cols}, far row first, left to right), "
            f"each: down in under a second, hold {HOLD_S:.1f} s at the depth, lift clear "
            "and move on. "
            "x to the right, y away from you, from the workspace's centre:",
            tuple(ps)))
    out.append(Step(
        "Write the true depth",
        "Next to each recording's video, a truth.csv (t_s, frame, contact, x_mm, y_mm, "
        "indentation_mm per frame): with an indenter, its depth past the first touch from "
        "the stage's log; with a finger, force / k from force.csv; contact 1 while the "
        "depth is above 0, x and y the press point's."))
    out.append(Step(
        "Fit",
        "fydpad calibrate indentation cal1 cal2 cal3 --out device.toml. It prints the "
        "plane's RMSE and the corrected one on held-out presses and writes the "
        "correction into [ir]; a held-out RMSE above 1 mm asks for the presses again, "
        "more carefully held."))
    return out


def protocol_text(workspace_mm: tuple[float, float] = (100.0, 70.0)) -> str:
    """The protocol as printed by ``fydpad calibrate indentation --protocol``."""
    head = (f"Indentation calibration protocol: {RECORDINGS} recordings, "
            f"{RECORDINGS * GRID[0] * GRID[1]} presses, {duration_s():.0f} s of recording "
            f"(about 2 minutes)")
    lines = [head, "=" * len(head)]
    for k, s in enumerate(steps(workspace_mm), 1):
        lines.append(f"{k}. {s.title}")
        lines.extend(textwrap.wrap(s.text, 88, initial_indent="   ", subsequent_indent="   "))
        if s.presses:
            lines.append("      #   x mm   y mm   depth mm")
            lines.extend(f"    {p.number:3d} {p.x_mm:+6.0f} {p.y_mm:+6.0f}   {p.depth_mm:6.0f}"
                         for p in s.presses)
    return "\n".join(lines)
