"""RCCL position equations (makeposition with EQ/TL, thesis 5.1-5.3): solving for T6, kinds, errors."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rccl.exceptions import PositionError
from rccl.position import EQ, TL, makeposition
from rccl.transform import T6, Trsf, inverse, rot, trsl


def test_z_t6_eq_b_gives_t6_equal_zinv_b():  # (5.1), (5.2)
    z = Trsf("Z", trsl(0.1, 0.0, 0.2) @ rot("z", 0.3))
    b = Trsf("B", trsl(0.3, 0.1, 0.0) @ rot("y", math.pi))
    p = makeposition("P", z, T6, EQ, b, TL, T6)
    assert np.allclose(p.solve(), inverse(z.matrix) @ b.matrix)
    assert np.allclose(p.tool_from_t6(), np.eye(4))


def test_tool_frame_and_t6_on_the_right():  # (5.3)
    z = Trsf("Z", trsl(0.1, 0.0, 0.2))
    tl = Trsf("TL", trsl(0.0, 0.0, 0.05))
    b = Trsf("B", trsl(0.3, 0.1, 0.0) @ rot("x", 0.2))
    p = makeposition("P", z, T6, tl, EQ, b, TL, tl)
    t6 = p.solve()
    assert np.allclose(z.matrix @ t6 @ tl.matrix, b.matrix)
    assert np.allclose(p.tool_from_t6(), tl.matrix)
    q = makeposition("Q", b, EQ, z, T6, tl, TL, tl)  # same equation written the other way round
    assert np.allclose(q.solve(), t6)


def test_changing_a_variable_component_moves_the_target():
    t = Trsf.trsl("T", 0.2, 0.0, 0.1, kind="variable")
    p = makeposition("P", T6, EQ, t, TL, T6)
    t.p = [0.25, 0.0, 0.1]
    assert np.allclose(p.solve()[:3, 3], [0.25, 0.0, 0.1])


def test_hold_is_frozen_at_snapshot_and_functional_runs():
    h = Trsf.trsl("H", 0.2, 0.0, 0.1, kind="hold")
    calls = []
    f = Trsf("F", kind="variable")
    f.bind(lambda tr: calls.append(tr.name))
    p = makeposition("P", T6, EQ, h, f, TL, T6)
    snap = p.snapshot()
    h.p = [0.3, 0.0, 0.1]
    assert np.allclose(p.solve(snap)[:3, 3], [0.2, 0.0, 0.1])   # the queued request keeps the old value
    assert np.allclose(p.solve()[:3, 3], [0.3, 0.0, 0.1])       # a new request sees the new one
    p.update_functional()
    assert calls == ["F"]


@pytest.mark.parametrize("items, match", [
    ((T6, Trsf("B"), TL, T6), "exactly one EQ"),
    ((T6, EQ, Trsf("B"), T6), "exactly one EQ and one TL"),
    ((Trsf("A"), EQ, Trsf("B"), TL, T6), "T6 must appear exactly once"),
    ((T6, T6, EQ, Trsf("B"), TL, T6), "T6 must appear exactly once"),
    ((T6, EQ, Trsf("B"), TL), "one tool transform"),
    ((T6, EQ, Trsf("B"), TL, Trsf("X")), "must follow T6"),
    ((T6, EQ, "B", TL, T6), "not a transform"),
])
def test_malformed_equations_name_the_position(items, match):
    with pytest.raises(PositionError, match=match) as info:
        makeposition("BAD", *items)
    assert "BAD" in str(info.value)


def test_end_event_counts_like_rccl():
    p = makeposition("P", T6, EQ, Trsf("B"), TL, T6)
    p.end.signal()           # the generator completed a motion to P
    assert p.end.count == -1
    p.end.wait(timeout=1.0)  # waitfor: increments to 0 (< 1) and returns at once
    assert p.end.count == 0
    with pytest.raises(TimeoutError, match="P.end"):
        p.end.wait(timeout=0.05)
    assert p.end.count == 0  # a failed wait leaves the count as it was
