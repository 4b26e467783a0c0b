"""Wire format v2 (docs/protocol.md): round trips, the documented byte layout, bad input."""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from teleop import protocol as P

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)


@given(seq=st.integers(0, 2**64 - 1), t=finite, x=finite, y=finite, z=finite,
       f=st.floats(width=64), contact=st.booleans(), hold=st.booleans(),
       operator_hold=st.booleans())
def test_sample_round_trip(seq, t, x, y, z, f, contact, hold, operator_hold):
    """Every field survives encode/decode bit for bit (NaN force included)."""
    s = P.Sample(seq, t, t + 1.0 if math.isfinite(t + 1.0) else t, x, y, z, f, contact, hold,
                 operator_hold)
    d = P.decode_sample(P.encode_sample(s))
    assert d.seq == seq and d.contact == contact and d.hold_mode == hold
    assert d.operator_hold == operator_hold
    assert (d.t_capture_s, d.x_mm, d.y_mm, d.z_mm) == (t, x, y, z)
    assert d.force_n == f or (math.isnan(f) and math.isnan(d.force_n))


def test_sample_layout_matches_the_document():
    """The bytes are exactly what docs/protocol.md tells another language to write."""
    s = P.Sample(7, 1.5, 1.6, 10.0, -5.0, 3.0, 2.0, True, False)
    doc = struct.pack("<4sBBHQdddddd", b"FYDT", 2, 1, 1, 7, 1.5, 1.6, 10.0, -5.0, 3.0, 2.0)
    assert P.encode_sample(s) == doc
    held = P.Sample(7, 1.5, 1.6, 10.0, -5.0, 3.0, 2.0, True, False, operator_hold=True)
    assert P.encode_sample(held)[6:8] == struct.pack("<H", 0x05)  # contact | operator hold
    assert P.decode_sample(P.encode_sample(held)).operator_hold
    assert P.SAMPLE_SIZE == 64


def test_state_layout_matches_the_document():
    st_ = P.State(P.STATUS_TRACKING, P.REASON_ACK, 9, 1.0, 2.0, 3.0, (1.0, 2.0, 3.0),
                  (4.0, 5.0, 6.0), 11, 2)
    doc = struct.pack("<4sBBBBQdddddddddII", b"FYDT", 2, 2, 1, 1, 9, 1.0, 2.0, 3.0,
                      1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 11, 2)
    assert P.encode_state(st_) == doc
    assert P.decode_state(doc) == st_
    assert P.STATE_SIZE == 96


@pytest.mark.parametrize("buf, msg", [
    (b"", "shorter than"),
    (b"FYDT\x01", "shorter than"),
    (b"XXXX" + bytes(60), "bad magic"),
    (b"FYDT\x01\x01" + bytes(58), "version 1"),
    (b"FYDT\x02\x02" + bytes(58), "type 2"),
    (b"FYDT\x02\x01" + bytes(50), "56 bytes"),
])
def test_garbage_and_truncated_are_refused_with_a_reason(buf, msg):
    with pytest.raises(P.ProtocolError, match=msg):
        P.decode_sample(buf)


def test_truncated_valid_sample_is_refused():
    full = P.encode_sample(P.Sample(1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, True))
    for n in range(len(full)):
        with pytest.raises(P.ProtocolError):
            P.decode_sample(full[:n])
