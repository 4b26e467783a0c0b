"""Framing of the qbrobotics packet protocol against bytes worked out from qbAPI."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from fydpad.motors import qb_protocol as qp


def test_frames_match_qbapi_byte_layout():
    # commActivate(id=1, on): ':' ':' 1 3 128 3 chk, chk = 128 ^ 3.
    assert qp.command(1, qp.CMD_ACTIVATE, bytes((3,))) == b"::\x01\x03\x80\x03\x83"
    # commGetMeasurements(id=2): the checksum of a lone command is the command itself.
    assert qp.command(2, qp.CMD_GET_MEASUREMENTS) == b"::\x02\x02\x84\x84"
    # commSetInputs(id=1, {300, -2}): big-endian int16s, LEN = 6.
    frame = qp.command(1, qp.CMD_SET_INPUTS, qp.int16s(300, -2))
    assert frame == b"::\x01\x06\x82\x01\x2c\xff\xfe" + bytes((0x82 ^ 0x01 ^ 0x2C ^ 0xFF ^ 0xFE,))
    assert qp.parse_int16s(b"\x01\x2c\xff\xfe") == (300, -2)
    assert qp.int16s(40000, -40000) == qp.int16s(32767, -32768)


def test_parser_splits_resyncs_and_counts():
    good = qp.command(1, qp.CMD_PING)
    bad = bytearray(qp.command(1, qp.CMD_GET_ACTIVATE))
    bad[-1] ^= 0x55
    p = qp.PacketParser(accept_ids=frozenset((1,)))
    stream = b"\x00\xffjunk" + good + bytes(bad) + b"::\x07\x09" + good
    out = []
    for i in range(0, len(stream), 3):  # arrives in pieces
        out += p.feed(stream[i:i + 3])
    assert [pkt.body for pkt in out] == [b"\x00", b"\x00"]
    assert p.checksum_errors == 1
    assert p.garbage_bytes >= 6


@given(st.lists(st.tuples(st.integers(1, 255), st.binary(min_size=1, max_size=40)),
                max_size=8),
       st.lists(st.binary(max_size=12).filter(lambda b: b":" not in b), min_size=9,
                max_size=9),
       st.integers(1, 7))
def test_any_frames_between_colon_free_garbage_come_through(frames, junk, chunk):
    stream = b"".join(j + qp.encode(i, body) for (i, body), j in zip(frames, junk,
                                                                      strict=False))
    p = qp.PacketParser()
    out = []
    for k in range(0, len(stream), chunk):
        out += p.feed(stream[k:k + chunk])
    assert [(x.device_id, x.body) for x in out] == frames
