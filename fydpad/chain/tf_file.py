"""The identified TF set on disk: one NPZ (no pickles) with a JSON header.

Arrays: ``freqs_hz`` (F), ``tf_real``/``tf_imag`` (S, F), ``coherence`` (S, F),
``stiffness_n_per_mm``, ``theta_rad``, ``force_mean_n``, ``force_sd_n`` (S), one row
per stiffness setting. ``header``: a JSON string with ``format`` ("fydpad-chain-tf"),
``version``, ``rate_hz``, ``channel``, ``input_unit``, ``output_unit``, ``band_hz``,
``excitation`` and ``provenance``. Layout and meaning: ``docs/chain.md``.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fydpad.chain import ChainError
from fydpad.chain.estimate import TfEstimate
from vision.strict_json import finite

FORMAT = "fydpad-chain-tf"
VERSION = 1
_ARRAYS = ("freqs_hz", "tf_real", "tf_imag", "coherence", "stiffness_n_per_mm", "theta_rad",
           "force_mean_n", "force_sd_n")


@dataclass(frozen=True)
class TfEntry:
    """The chain identified at one stiffness setting."""

    stiffness_n_per_mm: float
    theta_rad: float
    force_mean_n: float
    force_sd_n: float
    estimate: TfEstimate


def nearest_stiffness_index(ks: tuple[float, ...], stiffness_n_per_mm: float) -> int:
    """Index of the stiffness in ``ks`` nearest ``stiffness_n_per_mm``, the first of a
    tie; NaN asks for the softest. NaN entries are never chosen (ChainError if all are)."""
    want = stiffness_n_per_mm
    best, best_d = -1, math.inf
    for i, k in enumerate(ks):
        d = k if want != want else abs(k - want)  # NaN request: the smallest stiffness
        if d < best_d:  # a NaN distance never compares less
            best, best_d = i, d
    if best < 0:
        raise ChainError("TF set: no entry has a stiffness")
    return best


@dataclass
class TfSet:
    """TFs of one chain (channel, rate) over several stiffness settings."""

    rate_hz: float
    channel: str
    band_hz: tuple[float, float]
    entries: list[TfEntry]
    input_unit: str = "duty"
    output_unit: str = "m/s^2"
    excitation: dict = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)
    _ks: tuple[float, ...] | None = field(default=None, init=False, repr=False, compare=False)

    def nearest(self, stiffness_n_per_mm: float) -> TfEntry:
        """The entry identified at the stiffness nearest ``stiffness_n_per_mm`` (NaN:
        the softest, the fabric nearest its rest)."""
        return self.entries[self.nearest_index(stiffness_n_per_mm)]

    def nearest_index(self, stiffness_n_per_mm: float) -> int:
        """Index of :meth:`nearest`'s entry, from the stiffnesses cached at the first call
        (nothing allocated per call: the 1 kHz loop asks on every stiffness change)."""
        if self._ks is None or len(self._ks) != len(self.entries):
            self._ks = tuple(float(e.stiffness_n_per_mm) for e in self.entries)
        return nearest_stiffness_index(self._ks, stiffness_n_per_mm)

    def check(self, rate_hz: float, channel: str, path: str | Path = "TF file") -> None:
        """ChainError unless this set was identified on ``channel`` at ``rate_hz``."""
        if channel != self.channel or abs(rate_hz - self.rate_hz) > 1e-6 * rate_hz:
            raise ChainError(
                f"{path}: identified on channel '{self.channel}' at {self.rate_hz:g} Hz, "
                f"but this chain drives '{channel}' at {rate_hz:g} Hz: identify this chain "
                "with 'fydpad chain identify'")


def save_tf_set(tfs: TfSet, path: str | Path) -> Path:
    path = Path(path)
    if not tfs.entries:
        raise ChainError(f"{path}: no TF to write")
    f = tfs.entries[0].estimate.freqs_hz
    tf = np.stack([e.estimate.tf for e in tfs.entries])
    header = {"format": FORMAT, "version": VERSION, "rate_hz": tfs.rate_hz,
              "channel": tfs.channel, "input_unit": tfs.input_unit,
              "output_unit": tfs.output_unit, "band_hz": list(tfs.band_hz),
              "excitation": tfs.excitation, "provenance": tfs.provenance}
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as fh:  # an open file: np.savez would append ".npz" to a name
        np.savez(
            fh, header=np.array(json.dumps(finite(header), allow_nan=False)), freqs_hz=f,
            tf_real=tf.real, tf_imag=tf.imag,
            coherence=np.stack([e.estimate.coherence for e in tfs.entries]),
            **{k: np.array([getattr(e, k) for e in tfs.entries]) for k in
               ("stiffness_n_per_mm", "theta_rad", "force_mean_n", "force_sd_n")})
    return path


def load_tf_set(path: str | Path, rate_hz: float | None = None,
                channel: str | None = None) -> TfSet:
    """Read a TF set; ChainError naming the file and field when it is not one, or (given
    ``rate_hz`` and ``channel``) when it belongs to another chain."""
    path = Path(path)
    try:
        z = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise ChainError(f"{path}: no such file") from None
    except (OSError, ValueError, EOFError) as exc:
        raise ChainError(f"{path}: not a TF file (NPZ): {exc or 'empty'}") from None
    if not isinstance(z, np.lib.npyio.NpzFile):
        raise ChainError(f"{path}: not a TF file: a single array (.npy), not an NPZ archive")
    with z:
        missing = [k for k in ("header", *_ARRAYS) if k not in z.files]
        if missing:
            raise ChainError(f"{path}: not a TF file: missing '{missing[0]}'")
        try:
            h = json.loads(str(z["header"]))
        except json.JSONDecodeError as exc:
            raise ChainError(f"{path}: field 'header': bad JSON ({exc})") from None
        if h.get("format") != FORMAT:
            raise ChainError(f"{path}: field 'format' is {h.get('format')!r}, not {FORMAT!r}")
        if h.get("version") != VERSION:
            raise ChainError(f"{path}: field 'version' is {h.get('version')!r}; this fydpad "
                             f"reads version {VERSION}")
        for key in ("rate_hz", "channel", "band_hz"):
            if key not in h:
                raise ChainError(f"{path}: header field '{key}' missing")
        a = {k: np.asarray(z[k]) for k in _ARRAYS}
    f = a["freqs_hz"]
    s = a["stiffness_n_per_mm"].size
    for k in ("tf_real", "tf_imag", "coherence"):
        if a[k].shape != (s, f.size):
            raise ChainError(f"{path}: field '{k}' has shape {a[k].shape}, expected "
                             f"({s}, {f.size})")
    tf = a["tf_real"] + 1j * a["tf_imag"]
    entries = [TfEntry(float(a["stiffness_n_per_mm"][i]), float(a["theta_rad"][i]),
                       float(a["force_mean_n"][i]), float(a["force_sd_n"][i]),
                       TfEstimate(f, tf[i], a["coherence"][i])) for i in range(s)]
    tfs = TfSet(float(h["rate_hz"]), str(h["channel"]),
                (float(h["band_hz"][0]), float(h["band_hz"][1])), entries,
                h.get("input_unit", "duty"), h.get("output_unit", "m/s^2"),
                h.get("excitation", {}), h.get("provenance", {}))
    if rate_hz is not None and channel is not None:
        tfs.check(rate_hz, channel, path)
    return tfs
