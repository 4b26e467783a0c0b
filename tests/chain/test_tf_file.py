"""The TF file: round trip, and files of another chain or no TF file at all refused."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fydpad.chain import ChainError
from fydpad.chain.estimate import TfEstimate
from fydpad.chain.tf_file import TfEntry, TfSet, load_tf_set, save_tf_set


def make_set(rate_hz: float = 1000.0, channel: str = "vibration") -> TfSet:
    f = np.linspace(0, rate_hz / 2, 65)
    entries = [TfEntry(k, 0.5 * k, 0.3, 0.01,
                       TfEstimate(f, (1 + k) * np.exp(-1j * f / 100), np.full(65, 0.95)))
               for k in (0.45, 0.8)]
    return TfSet(rate_hz, channel, (10.0, 450.0), entries, excitation={"seed": 3},
                 provenance={"motors": "sim"})


def test_round_trip(tmp_path):
    p = save_tf_set(make_set(), tmp_path / "tf.npz")
    got = load_tf_set(p, 1000.0, "vibration")
    want = make_set()
    assert got.band_hz == (10.0, 450.0) and got.excitation == {"seed": 3}
    for a, b in zip(got.entries, want.entries, strict=True):
        assert a.stiffness_n_per_mm == b.stiffness_n_per_mm
        np.testing.assert_array_equal(a.estimate.tf, b.estimate.tf)
        np.testing.assert_array_equal(a.estimate.coherence, b.estimate.coherence)
    assert got.nearest(0.7).stiffness_n_per_mm == 0.8
    assert got.nearest(float("nan")).stiffness_n_per_mm == 0.45


def test_other_rate_or_channel_refused(tmp_path):
    p = save_tf_set(make_set(48000.0, "audio"), tmp_path / "audio.npz")
    with pytest.raises(ChainError, match=r"audio.npz: identified on channel 'audio' at "
                       r"48000 Hz, but this chain drives 'vibration' at 1000 Hz"):
        load_tf_set(p, 1000.0, "vibration")


def test_not_a_tf_file(tmp_path):
    bad = tmp_path / "x.npz"
    bad.write_text("hello")
    with pytest.raises(ChainError, match=r"x\.npz: not a TF file"):
        load_tf_set(bad)
    with pytest.raises(ChainError, match="no such file"):
        load_tf_set(tmp_path / "missing.npz")
    other = tmp_path / "other.npz"
    np.savez(other, a=np.zeros(3))
    with pytest.raises(ChainError, match="missing 'header'"):
        load_tf_set(other)
    empty = tmp_path / "empty.npz"
    empty.write_bytes(b"")
    with pytest.raises(ChainError, match=r"empty\.npz: not a TF file"):
        load_tf_set(empty)
    single = tmp_path / "single.npy"
    np.save(single, np.zeros(3))
    with pytest.raises(ChainError, match=r"single\.npy: not a TF file: a single array"):
        load_tf_set(single)


def test_wrong_format_or_version(tmp_path):
    p = save_tf_set(make_set(), tmp_path / "tf.npz")
    z = dict(np.load(p))
    h = json.loads(str(z["header"]))
    h["version"] = 99
    z["header"] = np.array(json.dumps(h))
    with open(tmp_path / "v99.npz", "wb") as fh:
        np.savez(fh, **z)
    with pytest.raises(ChainError, match="field 'version' is 99"):
        load_tf_set(tmp_path / "v99.npz")


class Uncomparable(TfEntry):
    """An entry that fails when compared, as two equal-looking entries do (their arrays
    make ``==`` ambiguous): selecting by index must never compare entries."""

    def __eq__(self, other):
        raise AssertionError("TF entries compared")

    __hash__ = None


def test_nearest_is_an_index_and_never_compares_entries():
    from fydpad.chain.live import LiveCompensator

    f = np.linspace(0, 500, 65)
    coh = np.full(65, 0.95)

    def entry(k, gain, cls=TfEntry):
        return cls(k, 0.5, 0.3, 0.01, TfEstimate(f, gain * np.exp(-1j * f / 100), coh))

    # Duplicate-looking entries: the same scalar fields, other arrays.
    a, b = entry(0.6, 1.0), entry(0.6, 2.0)
    with pytest.raises(ValueError, match="truth value of an array"):
        _ = a == b
    tfs = TfSet(1000.0, "vibration", (10.0, 450.0),
                [entry(0.6, 1.0, Uncomparable), entry(0.6, 2.0, Uncomparable),
                 entry(1.0, 3.0, Uncomparable), entry(0.45, 4.0, Uncomparable)])
    assert [tfs.nearest_index(k) for k in (0.6, 0.65, 0.9, 5.0, 0.0, float("nan"))] == \
        [0, 0, 2, 2, 3, 3]  # a tie: the first; NaN: the softest
    assert tfs.nearest(0.9) is tfs.entries[2]
    comp = LiveCompensator(tfs)
    for k, i in ((1.0, 2), (0.6, 0), (0.5, 3), (float("nan"), 3), (0.85, 2)):
        comp.select(k)
        assert comp.index == i
    assert comp.switches == 4
