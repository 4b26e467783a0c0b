"""IR readings of presses on the project's non-planar fabric, for the indentation tests:
a membrane pinned at the two rollers, sagging towards the finger.

Along x (the stretch direction, rollers at x = +-L) the fabric is a string pinned at the
rollers: straight from each roller to the edge of the finger's contact. Across y it is
free, and the sag decays away from the finger over a length that grows with depth (a
deeper finger stretches more fabric). The finger is a sphere of radius R: the contact
it wraps grows with depth. The fabric is flat (w = d) over the contact.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fydpad.fabric import Fabric
from vision.config import PAPER_SENSORS_MM
from vision.ir import distance_to_voltage_v

#: The project's one fabric model (fydpad/fabric.py): pinned at the rollers, sagging
#: towards the finger, not a plane. The sensing tests build their presses on it.
MembraneFabric = Fabric


def synth_ir(
    fabric: MembraneFabric, xf_mm: ArrayLike, yf_mm: ArrayLike, depth_mm: ArrayLike,
    rng: np.random.Generator, baseline_mm: ArrayLike = (100.0, 100.0, 100.0),
    sensors_mm=PAPER_SENSORS_MM, noise_v: float = 0.004, adc_bits: int = 10,
    vref_v: float = 5.0,
) -> NDArray[np.float64]:
    """IR voltages[n, 3]: eq. (1) inverted at the fabric's distance above each sensor,
    with sensor noise and the board's ADC quantisation."""
    xf, yf, d = (np.atleast_1d(np.asarray(a, np.float64)) for a in (xf_mm, yf_mm, depth_mm))
    s = np.asarray(sensors_mm, np.float64)
    z = np.asarray(baseline_mm, np.float64)[None, :] - fabric.deflection_mm(
        s[None, :, 0], s[None, :, 1], xf[:, None], yf[:, None], d[:, None])
    v = distance_to_voltage_v(z) + rng.normal(0.0, noise_v, z.shape)
    lsb = vref_v / 2**adc_bits
    return np.round(v / lsb) * lsb


def random_presses(
    n: int, rng: np.random.Generator, workspace_mm=(100.0, 70.0), max_depth_mm: float = 50.0,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Finger positions uniform over the workspace and depths uniform over 0-max."""
    w, h = workspace_mm
    return (rng.uniform(-w / 2, w / 2, n), rng.uniform(-h / 2, h / 2, n),
            rng.uniform(0.0, max_depth_mm, n))


def write_press_recording(
    recdir, rng: np.random.Generator, n_presses: int = 24,
    baseline_mm=(99.0, 101.0, 100.5), fabric: MembraneFabric | None = None,
) -> None:
    """A pad session recording of presses of known depth: each 0.5 s of rest, then 1 s
    pressing at a random place down to a random depth (10-50 mm) and back; IR at
    100 Hz, truth at 30 Hz. The video is two blank frames (only the sensors matter)."""
    from vision.recording import PadMeta, PadRecordingWriter

    fabric = fabric or MembraneFabric()
    meta = PadMeta(roi_px=(0, 0, 64, 48), workspace_mm=(100.0, 70.0), fps=30.0,
                   frame_size=(64, 48))
    rest_s, press_s = 0.5, 1.0
    cycle = rest_s + press_s
    duration = n_presses * cycle
    px, py, _ = random_presses(n_presses, rng)
    pd = rng.uniform(10.0, 50.0, n_presses)

    def state(t):
        k = np.minimum((t // cycle).astype(int), n_presses - 1)
        phase = (t - k * cycle - rest_s) / press_s
        contact = (phase > 0) & (phase < 1)
        depth = np.where(contact, pd[k] * np.sin(np.pi * np.clip(phase, 0, 1)), 0.0)
        return contact, px[k], py[k], depth

    with PadRecordingWriter(recdir, meta) as w:
        for _ in range(2):
            w.write_frame(np.full((48, 64, 3), 200, np.uint8))
        t_ir = np.arange(0.0, duration, 0.01)
        c, x, y, d = state(t_ir)
        v = synth_ir(fabric, x, y, d, rng, baseline_mm)
        for row in zip(t_ir, v[:, 0], v[:, 1], v[:, 2], strict=True):
            w.write_ir(*row)
        t_f = np.arange(0.0, duration, 1 / 30)
        c, x, y, d = state(t_f)
        for k, row in enumerate(zip(t_f, c, x, y, d, strict=True)):
            w.write_truth(row[0], k, bool(row[1]), row[2], row[3], row[4])
