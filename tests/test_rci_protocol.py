"""Frames, payload codecs and the decoder's resynchronisation (rci.protocol)."""
from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from rci import protocol as p
from rci.chg import CUR, POS, STOP, STOPCAL, Chg, UNVALUED, VALUED
from rci.exceptions import (ChecksumError, FrameLengthError, ProtocolError, SequenceGap,
                            UnknownFrameType)
from rci.how import How

i32 = st.integers(-2**31, 2**31 - 1)
u16 = st.integers(0, 0xFFFF)


@st.composite
def hows(draw):
    nj = draw(st.integers(1, 16))
    nadc = draw(st.integers(nj, 64))
    h = How(pos=np.array(draw(st.lists(i32, min_size=nj, max_size=nj)), dtype=np.int64),
            adcr=np.array(draw(st.lists(st.integers(-2048, 2047), min_size=nadc, max_size=nadc)), dtype=np.int64))
    h.pendant[:] = draw(st.lists(st.integers(0, 255), min_size=3, max_size=3))
    h.wc, h.status, h.state, h.exio, h.inport1, h.outport1 = (draw(u16) for _ in range(6))
    h.time_ns = draw(st.integers(0, 2**64 - 1))
    h.rate_hz = draw(st.integers(1, 1000))
    h.robot_overruns = draw(st.integers(0, 2**32 - 1))
    return h


@st.composite
def chgs(draw):
    nj = draw(st.integers(1, 16))
    c = Chg(nj=nj)
    for _, cmd in c.entries():
        if draw(st.booleans()):
            cmd.com = draw(st.integers(1, 255))
            if hasattr(cmd, "value"):
                cmd.value = draw(i32)
    return c


def _chg_state(c: Chg):
    # unvalued commands (end, stop, power_on, power_off) travel as one bit each
    return [(n, e.com if hasattr(e, "value") else bool(e.com), getattr(e, "value", 0) if e.com else 0)
            for n, e in c.entries()]


@given(hows(), st.integers(0, 2**32 - 1))
def test_how_round_trip(h, seq):
    frame = p.encode_frame(p.HOW, seq, p.encode_how(h))
    d = p.FrameDecoder()
    d.feed(frame)
    f = d.next_frame()
    assert (f.type, f.seq) == (p.HOW, seq)
    g = p.decode_how(f.payload, f.seq)
    assert np.array_equal(g.pos, h.pos) and np.array_equal(g.adcr, h.adcr)
    assert np.array_equal(g.pendant, h.pendant)
    for k in ("wc", "status", "state", "exio", "inport1", "outport1", "time_ns", "rate_hz", "robot_overruns"):
        assert getattr(g, k) == getattr(h, k), k
    assert g.cycle == seq
    assert d.next_frame() is None


@given(chgs())
def test_chg_round_trip(c):
    payload = p.encode_chg(c)
    assert len(payload) == p.chg_size(c.nj)
    assert _chg_state(p.decode_chg(payload)) == _chg_state(c)


def test_thesis_sizes_and_crc_check_value():
    assert p.crc16(b"123456789") == 0x29B1
    assert p.how_size(6, 16) == 87 and p.chg_size(6) == 102
    assert len(p.encode_frame(p.HOW, 1, p.encode_how(How()))) == 87 + 14


def test_session_payloads_round_trip():
    assert p.Hello.decode(p.Hello("puma260", 250, "me").encode()) == p.Hello("puma260", 250, "me")
    w = p.Welcome("microbo", 6, 16, 36, 5, p.MODE_LOCKSTEP, "simula 1")
    assert p.Welcome.decode(w.encode()) == w
    assert p.Start.decode(p.Start(1000).encode()).rate_hz == 1000
    assert p.ErrorMsg.decode(p.ErrorMsg(7, "bad").encode()) == p.ErrorMsg(7, "bad")
    assert p.Bye.decode(p.Bye(True).encode()).power_off is True


def test_hello_of_version_2_carries_the_pid_and_the_takeover_flag():
    h = p.Hello("puma260", 100, "prog", pid=4242, takeover=True)
    raw = h.encode()
    assert raw[0] == p.VERSION == 2 and p.Hello.decode(raw) == h
    assert p.Hello.decode(p.Hello("puma260", 36, "x", 7).encode()).takeover is False
    old = bytes([1]) + raw[1:]                        # a version-1 HELLO
    with pytest.raises(p.VersionError, match="version 1"):
        p.Hello.decode(old)


def test_text_values_are_refused_on_the_wire():
    c = Chg()
    c.motion[0].issue(POS, "12")
    with pytest.raises(ValueError, match=r"motion\[0\].*text"):
        p.encode_chg(c)


def test_float_values_are_rounded_and_nan_is_refused():
    c = Chg()
    c.motion[1].issue(CUR, 12.6)
    assert p.decode_chg(p.encode_chg(c)).motion[1].value == 13
    c.motion[2].issue(POS, float("nan"))
    with pytest.raises(ValueError, match=r"motion\[2\]"):
        p.encode_chg(c)


def test_garbage_before_and_between_frames_is_skipped():
    a = p.encode_frame(p.HOW, 1, p.encode_how(How()))
    b = p.encode_frame(p.BYE, 2, b"\x00")
    d = p.FrameDecoder()
    d.feed(b"\x00\xA5junk\xA5" + a + b"\xA5\xA5zz" + b)
    assert d.next_frame().seq == 1
    assert d.next_frame().seq == 2
    assert d.skipped == len(b"\x00\xA5junk\xA5") + len(b"\xA5\xA5zz")


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(0, 10_000), min_size=1, max_size=8), st.data())
def test_corruption_is_named_and_decoder_recovers(flip_positions, data):
    """Flip bits anywhere in a stream of frames: no damaged frame is ever delivered,
    every undamaged frame after the damage is still delivered, and every drop is named."""
    frames = [p.encode_frame(p.HOW, k, p.encode_how(How())) for k in range(10)]
    stream = bytearray(b"".join(frames))
    bounds = np.cumsum([0] + [len(f) for f in frames])
    for pos in flip_positions:
        stream[pos % len(stream)] ^= 1 << data.draw(st.integers(0, 7))
    damaged = {k for k in range(10) if bytes(stream[bounds[k]:bounds[k + 1]]) != frames[k]}
    d = p.FrameDecoder()
    d.feed(bytes(stream))
    got, errors = [], 0
    for _ in range(10_000):
        try:
            f = d.next_frame()
        except ProtocolError as e:
            assert isinstance(e, (ChecksumError, FrameLengthError, UnknownFrameType, ProtocolError))
            errors += 1
            continue
        if f is None:
            break
        got.append(f.seq)
    assert set(got) <= set(range(10))
    for k in set(range(10)) - damaged:
        assert k in got, f"undamaged frame {k} lost (damaged: {sorted(damaged)})"
    assert not (set(got) & damaged), "a damaged frame was delivered"
    # a damaged frame is either named (an error) or lost with its sync pair (the session's
    # sequence check then names it): never silently accepted
    assert errors >= 1 or not damaged or len(got) < 10


def test_bad_checksum_raises_chksum_error_mapped_to_r_chksum():
    f = bytearray(p.encode_frame(p.HOW, 5, p.encode_how(How())))
    f[20] ^= 0xFF
    d = p.FrameDecoder()
    d.feed(bytes(f))
    with pytest.raises(ChecksumError) as e:
        d.next_frame()
    assert e.value.code == 11  # R_CHKSUM
    assert d.next_frame() is None


def test_bad_length_unknown_type_and_version():
    head = struct.pack("<BBIH", 1, p.HOW, 1, 5000)
    d = p.FrameDecoder()
    d.feed(p.SYNC + head + struct.pack("<H", p.crc16(head)))
    with pytest.raises(FrameLengthError):
        d.next_frame()
    d = p.FrameDecoder()
    d.feed(p.encode_frame(0x77, 3, b"x"))
    with pytest.raises(UnknownFrameType, match="0x77"):
        d.next_frame()
    head = struct.pack("<BBIH", 9, p.HOW, 1, 0)
    body = head + struct.pack("<H", p.crc16(head))
    d.feed(p.SYNC + body + struct.pack("<H", p.crc16(body)))
    with pytest.raises(ProtocolError, match="version 9"):
        d.next_frame()


def test_payload_of_wrong_size_is_a_length_error():
    good = p.encode_how(How())
    with pytest.raises(FrameLengthError, match="expected 87"):
        p.decode_how(good[:-1], 1)
    with pytest.raises(FrameLengthError):
        p.decode_chg(p.encode_chg(Chg())[:-2])


def test_sequence_gap_is_named():
    s = p.SequenceChecker()
    s.check(0xFFFFFFFF)
    s.check(0)             # wraps
    with pytest.raises(SequenceGap) as e:
        s.check(2)
    assert (e.value.expected, e.value.got) == (1, 2)


def test_chg_com_is_consumed_by_clear_and_names_pending():
    c = Chg()
    c.motion[0].issue(STOP)
    c.motion[1].issue(STOPCAL, 100)
    c.power_on.issue()
    assert c.pending() == ["motion[0]", "motion[1]", "power_on"]
    c.clear()
    assert c.pending() == [] and c.motion[1].value == 100
    assert len(VALUED) == 8 and len(UNVALUED) == 4
