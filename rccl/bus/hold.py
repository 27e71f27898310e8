"""Which planning level holds an arm process: proved by a key agreed at its first request.

An arm process obeys one planning level at a time, as a robot obeys one controller. A
planning level (``rccl.bus.planning.BusEvents``) takes an arm with a ``hold`` request that
carries an X25519 public key; the arm process answers with its own if nobody holds the
arm (or its holder was given up, or released it), and both derive two keys
(``rci.bus.frames.Handshake``): one seals every later request (encrypted and
authenticated, a counter that only rises: ``move``, ``free``, ``abort``, ``close``,
``release``), the other authenticates the planning level's start_ev / stop_ev messages
(an HMAC per arm addressed). What anyone else sends is refused (``ArmHeld``) or dropped
and counted: a planner id copied from the bus is not enough. ``info`` (read only) needs no hold
(the holder's is sealed too). The arm process answers the holder's requests, their seal
checked on arrival (``ArmHold.from_holder``), ahead of anyone else's.
"""
from __future__ import annotations

import hashlib
import hmac
import json
import threading
from typing import Any, Callable

from rci.bus.frames import Handshake, KeyAgreementError, Opener, Sealer

from .wire import ArmHeld

OPEN_OPS = ("info", "hold")          # what a planning level may ask without holding the arm


def set_digest(message: dict) -> bytes:
    """The bytes a start_ev / stop_ev message's MAC covers."""
    return json.dumps([str(message["flag"]), int(message["code"]),
                       [[str(a), int(s)] for a, s in message["efts"]],
                       str(message["planner"]), int(message["seq"])], separators=(",", ":")).encode()


def _mac(key: bytes, data: bytes) -> str:
    return hmac.new(key, data, hashlib.sha256).hexdigest()[:32]


def _context(cell: str, arm: str, planner: str) -> str:
    return f"rcci/{cell}/arm/{arm}/held-by/{planner}"


class PlannerHolds:
    """The planning side: per arm, the keys of its hold (``ask(arm, dict) -> dict`` sends one
    request in the clear and returns the answer, raising what the arm refused)."""

    def __init__(self, cell: str, planner: str, ask: Callable[[str, dict], dict]) -> None:
        self.cell, self.planner = cell, planner
        self._ask = ask
        self._keys: dict[str, tuple[Sealer, bytes]] = {}
        self._lock = threading.Lock()

    def wire(self, arm: str, request: dict) -> dict:
        """What to send for ``request`` (which names this planning level): in the clear for
        ``info`` to an arm it does not hold, sealed under the arm's hold otherwise (taking the hold first)."""
        with self._lock:
            held = arm in self._keys
        if request.get("op") in OPEN_OPS and not held:      # once it holds the arm, its info is sealed too:
            return request                                  # answered ahead of a flood of others' (rccl.bus.arm)
        sealer = self._hold(arm)[0]
        return {"planner": self.planner, "silence": request.get("silence"),
                "sealed": sealer.seal(json.dumps(request).encode()).hex()}

    def _hold(self, arm: str) -> tuple[Sealer, bytes]:
        with self._lock:
            if arm in self._keys:
                return self._keys[arm]
        hs = Handshake()
        answer = self._ask(arm, {"op": "hold", "planner": self.planner, "key": hs.public.hex()})
        try:
            arm_public = bytes.fromhex(str(answer["key"]))
            request_key, set_key = hs.keys(arm_public, hs.public, arm_public, _context(self.cell, arm, self.planner))
        except (KeyError, ValueError, KeyAgreementError) as exc:
            raise ArmHeld(f"arm {arm!r}: its answer to hold cannot be used ({exc})") from None
        with self._lock:
            self._keys[arm] = (Sealer(request_key), set_key)
            return self._keys[arm]

    def macs(self, message: dict, arms: set[str]) -> dict[str, str]:
        """The MAC of a start_ev / stop_ev message for each arm addressed that this level holds."""
        data = set_digest(message)
        with self._lock:
            return {a: _mac(self._keys[a][1], data) for a in arms if a in self._keys}

    def held(self) -> list[str]:
        with self._lock:
            return list(self._keys)


class ArmHold:
    """The arm process's side: who holds it, the keys, and what was refused (counted)."""

    def __init__(self, cell: str, arm: str) -> None:
        self.cell, self.arm = cell, arm
        self.holder: str | None = None
        self._opener: Opener | None = None
        self._set_key = b""
        self.refused = 0                       # requests and set messages not from the holder

    def take(self, r: dict, holder_gone: Callable[[str], bool]) -> dict:
        """A ``hold`` request: the answer (the arm's public key), or ArmHeld."""
        planner = str(r.get("planner"))
        if self.holder not in (None, planner) and not holder_gone(self.holder):
            self.refused += 1
            raise ArmHeld(f"arm {self.arm!r} is held by the planning level {self.holder}: it obeys one planning "
                          "level at a time (the holder releases it when it closes, or is given up when it is lost)")
        hs = Handshake()
        try:
            request_key, set_key = hs.keys(bytes.fromhex(str(r["key"])), bytes.fromhex(str(r["key"])), hs.public,
                                           _context(self.cell, self.arm, planner))
        except (KeyError, ValueError, KeyAgreementError) as exc:
            self.refused += 1
            raise ArmHeld(f"arm {self.arm!r}: a hold request with an unusable key ({exc})") from None
        self.holder, self._opener, self._set_key = planner, Opener(request_key), set_key
        return {"held": True, "key": hs.public.hex()}

    def open(self, r: dict) -> dict:
        """The request inside a sealed one from the holder; ArmHeld for anything else."""
        planner, sealed = str(r.get("planner")), r.get("sealed")
        if sealed is None or planner != self.holder or self._opener is None:
            self.refused += 1
            raise ArmHeld(f"arm {self.arm!r}: {r.get('op', 'a request')!r} refused: only the planning level that "
                          f"holds this arm ({self.holder or 'none yet: hold it first'}) may ask it, sealed under its "
                          "hold")
        try:
            inner = self._opener.open(bytes.fromhex(str(sealed)))
            request = json.loads(inner) if inner is not None else None
        except ValueError:
            request = None
        if not isinstance(request, dict) or str(request.get("planner")) != planner:
            self.refused += 1
            raise ArmHeld(f"arm {self.arm!r}: a request not sealed by its holder ({self._opener.rejected.describe()})")
        return request

    def from_holder(self, payload: bytes) -> bool:
        """On a Zenoh thread, changing nothing: whether a request (its payload) is sealed by the
        holder (``Opener.peek``), to be answered ahead of anyone else's (``rci.bus.guard.Lanes``)."""
        opener, holder = self._opener, self.holder
        if opener is None or holder is None:
            return False
        try:
            r = json.loads(payload)
            return str(r.get("planner")) == holder and opener.peek(bytes.fromhex(str(r["sealed"])))
        except (ValueError, KeyError, TypeError, AttributeError):
            return False

    def release(self, planner: str) -> None:
        if planner == self.holder:
            self.holder, self._opener, self._set_key = None, None, b""

    def set_ok(self, message: dict[str, Any]) -> bool:
        """A start_ev / stop_ev message from the holder, with this arm's MAC right."""
        mac = (message.get("mac") or {}).get(self.arm)
        ok = (self.holder is not None and str(message.get("planner")) == self.holder and isinstance(mac, str)
              and hmac.compare_digest(_mac(self._set_key, set_digest(message)), mac))
        self.refused += not ok
        return ok
