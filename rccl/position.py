"""Position equations (RCCL's POS, thesis 5.1-5.3): a transform equation containing T6, solved for T6.

``makeposition("P0", z, T6, EQ, b, TL, T6)`` builds the equation Z T6 = B (5.1) with the
tool frame at link 6; ``makeposition("P1", z, T6, tl, EQ, b, TL, tl)`` builds Z T6 TL = B
(5.3) with the tool frame ``tl``. ``EQ`` marks the equals sign and ``TL`` the end of the
equation; the transform after ``TL`` names the tool frame. T6 may stand on either side.

The equation is solved every time the position is evaluated (once per sample by the
trajectory generator), so changing a variable component, or a functional component
changing itself, moves the target (5.3.1, 5.4.4). Each position carries an ``end`` event
(5.3.3) that the generator signals each time it completes a motion to it.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .exceptions import PositionError
from .sync import Event
from .transform import T6, Trsf, inverse


class _Key:
    __slots__ = ("name",)

    def __init__(self, name: str) -> None:
        self.name = name

    def __repr__(self) -> str:
        return self.name


EQ = _Key("EQ")  # the '=' of a position equation
TL = _Key("TL")  # end of the equation; the next argument is the tool transform


@dataclass(frozen=True)
class Snapshot:
    """Values of a position's ``hold`` transforms, frozen when a motion request is queued."""

    values: dict[int, np.ndarray]


class Position:
    """A position equation  L1..Lk T6 R1..Rm = Q1..Qn, solved as T6 = (L1..Lk)^-1 Q1..Qn (R1..Rm)^-1.

    ``tool_from_t6`` = R1..Rj (j: the tool's index among the R's; identity when the tool
    is T6) is the tool frame seen from link 6, so the tool frame in the base is T6 R1..Rj.
    """

    def __init__(self, name: str, left: Sequence[Trsf], t6_right: Sequence[Trsf],
                 other: Sequence[Trsf], tool: Trsf) -> None:
        self.name = name
        self.left = tuple(left)        # transforms before T6 on T6's side
        self.right = tuple(t6_right)   # transforms after T6 on T6's side
        self.other = tuple(other)      # the other side of the equation
        self.tool = tool
        if tool is T6:
            self._ntool = 0
        else:
            idx = [i for i, t in enumerate(self.right) if t is tool]
            if not idx:
                raise PositionError(
                    f"position {name!r}: the tool transform {tool.name!r} must follow T6 on T6's side of the equation")
            self._ntool = idx[0] + 1
        self.end = Event(f"{name}.end")
        seen: dict[int, Trsf] = {}
        for t in self.left + self.right + self.other:
            seen.setdefault(id(t), t)
        self._unique = tuple(seen.values())

    # -- evaluation (called at the control level every sample) -------------------------
    def transforms(self) -> tuple[Trsf, ...]:
        """Every transform of the equation except T6 (each once)."""
        return self._unique

    def snapshot(self) -> Snapshot:
        """Freeze the current values of the ``hold`` transforms (done when a motion is queued)."""
        return Snapshot({id(t): t.value_array for t in self.transforms() if t.kind == "hold"})

    def update_functional(self, skip: tuple[Trsf, ...] = ()) -> None:
        """Call each functional transform's function once (the generator does this every sample).

        ``skip``: transforms already updated this sample (those of another position in play
        during a transition), so a transform shared by both is still called once per sample.
        """
        for t in self._unique:
            if t.fn is not None and t.kind == "functional" and not any(t is u for u in skip):
                t.fn(t)

    def _value(self, t: Trsf, snap: Snapshot | None) -> np.ndarray:
        if snap is not None:
            v = snap.values.get(id(t))
            if v is not None:
                return v
        return t.value_array

    def solve(self, snap: Snapshot | None = None) -> np.ndarray:
        """T6 (base to link 6, 4x4, metres) that satisfies the equation with the current values."""
        rhs = np.eye(4)
        for t in self.other:
            rhs = rhs @ self._value(t, snap)
        if self.left:
            lft = np.eye(4)
            for t in self.left:
                lft = lft @ self._value(t, snap)
            rhs = inverse(lft) @ rhs
        if self.right:
            rgt = np.eye(4)
            for t in self.right:
                rgt = rgt @ self._value(t, snap)
            rhs = rhs @ inverse(rgt)
        return rhs

    def tool_from_t6(self, snap: Snapshot | None = None) -> np.ndarray:
        """The tool frame seen from link 6 (identity when the tool is T6)."""
        out = np.eye(4)
        for t in self.right[: self._ntool]:
            out = out @ self._value(t, snap)
        return out

    def __repr__(self) -> str:
        side = " ".join([t.name for t in self.left] + ["T6"] + [t.name for t in self.right])
        other = " ".join(t.name for t in self.other) or "I"
        return f"Position({self.name!r}: {side} = {other}, tool {self.tool.name})"


def makeposition(name: str, *items) -> Position:
    """Build a position from a transform equation: ``makeposition("P", z, T6, EQ, b, TL, T6)``.

    Items before ``EQ`` form the left side, items between ``EQ`` and ``TL`` the right side,
    and the single item after ``TL`` is the tool frame (T6 or a transform following T6).
    Raises ``PositionError`` naming the position for a malformed equation.
    """
    if not isinstance(name, str):
        raise PositionError(f"makeposition: the first argument must be the position's name, got {name!r}")
    where = f"makeposition({name!r})"
    n_eq = sum(1 for x in items if x is EQ)
    n_tl = sum(1 for x in items if x is TL)
    if n_eq != 1 or n_tl != 1:
        raise PositionError(f"{where}: needs exactly one EQ and one TL (got {n_eq} EQ, {n_tl} TL)")
    i_eq = next(i for i, x in enumerate(items) if x is EQ)
    i_tl = next(i for i, x in enumerate(items) if x is TL)
    if i_tl < i_eq:
        raise PositionError(f"{where}: TL must come after EQ")
    lhs, rhs, tail = list(items[:i_eq]), list(items[i_eq + 1:i_tl]), list(items[i_tl + 1:])
    if len(tail) != 1:
        raise PositionError(f"{where}: exactly one tool transform must follow TL (got {len(tail)})")
    for x in lhs + rhs + tail:
        if not isinstance(x, Trsf):
            raise PositionError(f"{where}: {x!r} is not a transform (Trsf)")
    n_t6 = sum(1 for x in lhs + rhs if x is T6)
    if n_t6 != 1:
        raise PositionError(f"{where}: T6 must appear exactly once in the equation (found {n_t6})")
    side, other = (lhs, rhs) if any(x is T6 for x in lhs) else (rhs, lhs)
    k = next(i for i, x in enumerate(side) if x is T6)
    return Position(name, side[:k], side[k + 1:], other, tail[0])


def joint_position(name: str, kin, q) -> Position:
    """A position whose T6 is the forward kinematics of joint angles q (rad), e.g. RCCL's ``park``.

    Built as the equation T6 = FK(q) with a const transform, so it behaves like any other.
    """
    q = np.asarray(q, dtype=float)
    n = len(getattr(kin, "revolute", getattr(kin, "LOWER", q)))   # the arm's joints (6; 7 on a redundant arm)
    if q.shape != (n,) or not np.all(np.isfinite(q)):
        raise PositionError(f"joint_position({name!r}): q must be {n} finite joint angles (rad), got {q!r}")
    base_to_t6 = Trsf(name.upper(), kin.fk(q))
    pos = makeposition(name, T6, EQ, base_to_t6, TL, T6)
    pos.joints = q  # type: ignore[attr-defined]  # the joint angles it was built from (config hint)
    return pos
