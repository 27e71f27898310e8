"""An attacker on the cell's network, for tests/test_security_netns.py: ``python tests/security_attacker.py KIND ...``.

Each kind tries what the independent probe of issue 26 did, with what that kind of
attacker has, and prints one JSON line saying what it managed (the test asserts on it and
on simula's own record):

``nocert ENDPOINT KEY``          no certificate: a plain TCP and a TLS session to the robot's endpoint
``observer CONFIG KEY OWNER``    a valid certificate of the cell that is not the controller's
``insider CONFIG KEY OWNER SEQ`` the controller's own credentials, but not the owner's connection
``flood-hello CONFIG KEY N S``   N hello queries as fast as it can send them, and more until S seconds
                                 have passed; a line ``{"flooding": ...}`` once 1000 are sent
``link-on-go CONFIG KEY``        a controller ready to start: it asks when told (a line on stdin)
``flood-frames CONFIG KEY OWNER N``    N garbage, N truncated-CHG and oversized publications on the owner's key

``arm-attacks INSIDER OBSERVER FOREIGN CELL PLANNER SERIAL N``
                                 on a workcell's bus: with the planning level's own credentials
                                 (INSIDER), the holder's id copied: requests and start_ev of the
                                 held motion SERIAL; with an observer's (OBSERVER): a shared value,
                                 start_ev, forged flags, a request; with another CA's (FOREIGN): join;
                                 then N ``info`` requests as fast as it can send them (INSIDER),
                                 a line ``{"flooding": ...}`` once 1000 are sent

KEY is the robot's key (``lab/puma``), OWNER the owner's connection id.
"""
from __future__ import annotations

import json
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from rci import protocol  # noqa: E402
from rci.bus.session import open_session  # noqa: E402
from rci.chg import POS, Chg  # noqa: E402
from rci.exceptions import RCIError  # noqa: E402
from rci.session import Session  # noqa: E402


def _forged_chg(seq: int, target_counts: int, release: bool = False) -> bytes:
    """A CHG frame with a valid checksum: joint 1 to ``target_counts``, or the release flags."""
    chg = Chg()
    if release:
        chg.end.issue()
        chg.power_off.issue()
    else:
        chg.motion[0].issue(POS, target_counts)
    return protocol.encode_frame(protocol.CHG, seq, protocol.encode_chg(chg))


def _owners(session, key: str, timeout: float = 1.0) -> list[str]:
    """The connection ids whose liveliness tokens this session can see."""
    ids = []
    for reply in session.liveliness().get(f"rcci/{key}/c/*", timeout=timeout):
        if reply.ok is not None:
            ids.append(str(reply.ok.key_expr).rsplit("/", 1)[-1])
    return ids


REFUSED_WITHIN_S = 2.0    # a controller the robot never answers gives up after this (one it serves: ms)


def _try_link(url: str, hello_s: float = 5.0) -> str:
    """Try to take the robot with a controller of our own, asking at most ``hello_s`` for an
    answer to its hello (the link's default is 5 s); what happened, in words."""
    import functools

    import rci.session
    from rci.link import open_link
    rci.session.open_link = functools.partial(open_link, connect_timeout=hello_s)
    s = Session(url, "puma260", rate_hz=50, on_error="raise", signals=False, lock_memory=False,
                realtime=False, start_timeout=2.0)
    try:
        s.open()
        s.close()
        return "opened"
    except RCIError as exc:
        return f"{type(exc).__name__}: {exc}"


def _inject(session, key: str, owner: str, seq: int, n: int) -> int:
    """Forged CHGs (joint 1 by ~20 deg, and releases) on the owner's command key, bare and wrapped
    in a made-up counter and tag; returns the publications made."""
    down = f"rcci/{key}/c/{owner}/down"
    made = 0
    for i in range(n):
        frame = _forged_chg(seq + i, 200_000 + 1000 * i, release=(i % 10 == 9))
        session.put(down, frame)
        session.put(down, (10**9 + i).to_bytes(8, "big") + frame + bytes(16))
        made += 2
    return made


def nocert(endpoint: str, key: str) -> dict:
    out: dict = {}
    host_port = endpoint.split("/", 1)[1]
    for scheme in ("tcp", "tls"):
        s = open_session(connect=(f"{scheme}/{host_port}",))
        out[f"{scheme}_ids_seen"] = len(_owners(s, key))
        out[f"{scheme}_put"] = _inject(s, key, "0" * 12, 1, 10)
        s.close()
        out[f"{scheme}_link"] = _try_link(f"zenoh/{key}?connect={scheme}/{host_port}", REFUSED_WITHIN_S)
    return out


def observer(config: str, key: str, owner: str) -> dict:
    s = open_session(config=config)
    seen: list = []
    sub = s.declare_subscriber(f"rcci/{key}/c/{owner}/up", lambda smp: seen.append(1))
    out = {"ids_seen": len(_owners(s, key))}
    time.sleep(1.0)
    out["frames_read"] = len(seen)            # the robot's frames to the owner it could read
    out["put"] = _inject(s, key, owner, 1, 50)
    time.sleep(0.5)
    sub.undeclare()
    s.close()
    out["link"] = _try_link(f"zenoh/{key}?config={config}", REFUSED_WITHIN_S)
    return out


def insider(config: str, key: str, owner: str, seq: int) -> dict:
    """The controller's credentials and the owner's connection id and cycle (as if learnt
    through a router of the cell): try to read its frames, forge CHGs with its seq and a valid
    checksum (bare, and wrapped in a made-up counter and tag), a release, a bad checksum;
    replay what it could read; try to connect."""
    s = open_session(config=config)
    out: dict = {"ids_seen": len(_owners(s, key))}
    ups: list[bytes] = []
    downs: list[bytes] = []
    s1 = s.declare_subscriber(f"rcci/{key}/c/{owner}/up", lambda smp: ups.append(smp.payload.to_bytes()))
    s2 = s.declare_subscriber(f"rcci/{key}/c/{owner}/down", lambda smp: downs.append(smp.payload.to_bytes()))
    time.sleep(1.0)
    out["up_read"], out["down_read"] = len(ups), len(downs)
    # a HOW in the clear would start with the frame's sync bytes after the counter
    out["how_readable"] = sum(1 for u in ups if u[8:10] == protocol.SYNC or u[:2] == protocol.SYNC)
    captured = list(downs)        # the owner's own sealed CHGs, if any (later ones would include ours)
    out["forged"] = _inject(s, key, owner, seq + 50, 100)        # about the cycle the robot is at by then
    replayed = 0
    for sealed in captured[-50:]:
        s.put(f"rcci/{key}/c/{owner}/down", sealed)
        replayed += 1
    out["replayed"] = replayed
    bad = bytearray(_forged_chg(seq + 60, 300_000))
    bad[-1] ^= 0xFF                        # a bad checksum: it once made simula end the owner's control
    for _ in range(10):
        s.put(f"rcci/{key}/c/{owner}/down", bytes(bad))
    out["bad_checksum"] = 10
    time.sleep(0.3)
    s1.undeclare()
    s2.undeclare()
    s.close()
    out["link"] = _try_link(f"zenoh/{key}?config={config}")
    return out


def flood_hello(config: str, key: str, n: int, min_s: float) -> dict:
    """Hello queries from one session (bad public keys) as fast as it can: ``n``, and more
    until ``min_s`` seconds have passed (so that a controller can ask in the middle of it)."""
    s = open_session(config=config)
    t0 = time.monotonic()
    sent = 0
    while sent < n or time.monotonic() - t0 < min_s:
        s.get(f"rcci/{key}/hello", lambda reply: None,
              payload=json.dumps({"id": f"{sent:012x}", "key": "00" * 32}).encode(), timeout=1.0)
        sent += 1
        if sent == 1000:
            print(json.dumps({"flooding": time.monotonic()}), flush=True)
    t_end = time.monotonic()
    time.sleep(1.0)
    s.close()
    return {"sent": sent, "seconds": t_end - t0, "t_end": t_end}


def link_on_go(config: str, key: str) -> dict:
    """A controller started ahead (its imports done), which asks for the robot when a line
    comes on stdin: how long it took to be answered (``time.monotonic()``, one clock per host)."""
    print(json.dumps({"ready": True}), flush=True)
    sys.stdin.readline()
    t_asked = time.monotonic()
    link = _try_link(f"zenoh/{key}?config={config}")
    return {"link": link, "t_asked": t_asked, "t_answered": time.monotonic()}


def flood_frames(config: str, key: str, owner: str, n: int) -> dict:
    s = open_session(config=config)
    down = f"rcci/{key}/c/{owner}/down"
    pub = s.declare_publisher(down)
    chg = _forged_chg(5, 250_000)
    t0 = time.monotonic()
    rnd = os.urandom(64)
    for i in range(n):
        pub.put(rnd[i % 32:i % 32 + 32])                  # garbage
    for i in range(n):
        pub.put(chg[: 1 + i % (len(chg) - 1)])             # truncated CHGs
    for size in (4096, 65536, 1 << 20):
        pub.put(os.urandom(size))                          # oversized
    sent_s = time.monotonic() - t0
    time.sleep(1.0)
    pub.undeclare()
    s.close()
    return {"sent": 2 * n + 3, "seconds": sent_s}


def _ask(session, key: str, payload: dict) -> dict | None:
    from rci.bus import decode, encode
    replies = [r for r in session.get(key, payload=encode(payload), timeout=3.0) if r.ok is not None]
    return decode(replies[0].ok.payload.to_bytes()) if replies else None


def arm_attacks(insider: str, observer: str, foreign: str, cell: str, planner: str, serial: int, n: int) -> dict:
    """What tests/test_security_arm_netns.py tries against an arm process held by ``planner``."""
    from rci.bus import encode
    request = f"rcci/{cell}/arm/puma/request"
    out: dict = {}
    s = open_session(config=insider, client=True)
    who = {"planner": planner, "silence": 0.5}                      # the holder's id, copied from the bus
    far = {"name": "far", "joints": [0.5, 0.0, 0.0, 0.0, 0.0, 0.0]}
    out["refusals"] = [_ask(s, request, {"op": op, **who, **extra}) for op, extra in (
        ("move", {"position": far, "start": None}), ("abort", {}), ("close", {}), ("free", {"serials": [serial]}))]
    out["refusals"].append(_ask(s, request, {**who, "sealed": "00" * 60}))               # a made-up seal
    out["refusals"].append(_ask(s, request, {"op": "hold", "planner": "intruder", "key": "11" * 32}))
    acks: list = []
    sub = s.declare_subscriber(f"rcci/{cell}/arm/puma/ack", lambda smp: acks.append(1))
    for mac in ({}, {"puma": "00" * 16}):                             # start_ev of the held motion, no key
        s.put(f"rcci/{cell}/flags/set", encode({"flag": "start", "code": 5, "efts": [["puma", serial]],
                                                "planner": planner, "seq": 10_000 + len(mac), "mac": mac}))
    # an observer of the cell: it reads, and writes nothing
    o = open_session(config=observer, client=True)
    o.put(f"rcci/{cell}/shared/plan", encode(99))
    o.put(f"rcci/{cell}/flags/set", encode({"flag": "start", "code": 5, "efts": [["puma", serial]],
                                            "planner": planner, "seq": 20_000, "mac": {}}))
    o.put(f"rcci/{cell}/flags/puma/{serial}", encode({"arm": "puma", "serial": serial, "status": 1, "start": 5,
                                                      "version": 10**6}))
    out["observer_info"] = _ask(o, request, {"op": "info", "planner": "observer"})
    out["observer_flags_query"] = sum(1 for r in o.get(f"rcci/{cell}/flags/puma/*", timeout=2.0) if r.ok is not None)
    time.sleep(0.5)
    out["acks"] = len(acks)
    sub.undeclare()
    o.close()
    try:
        open_session(config=foreign, client=True).close()
        out["foreign"] = "joined"
    except Exception as exc:
        out["foreign"] = f"{type(exc).__name__}: {exc}"
    payload = encode({"op": "info", "planner": planner, "silence": 0.5})
    t0 = time.monotonic()
    for i in range(n):
        s.get(request, lambda _: None, timeout=1.0, payload=payload)
        if i == 1000:
            print(json.dumps({"flooding": time.monotonic()}), flush=True)
    out["t_flood_end"] = time.monotonic()
    out["flood_s"] = out["t_flood_end"] - t0
    time.sleep(1.0)
    s.close()
    return out


def main(argv: list[str]) -> int:
    kind, args = argv[0], argv[1:]
    if kind == "nocert":
        out = nocert(*args)
    elif kind == "observer":
        out = observer(*args)
    elif kind == "insider":
        out = insider(args[0], args[1], args[2], int(args[3]))
    elif kind == "flood-hello":
        out = flood_hello(args[0], args[1], int(args[2]), float(args[3]))
    elif kind == "arm-attacks":
        out = arm_attacks(*args[:5], int(args[5]), int(args[6]))
    elif kind == "link-on-go":
        out = link_on_go(args[0], args[1])
    elif kind == "flood-frames":
        out = flood_frames(args[0], args[1], args[2], int(args[3]))
    else:
        raise SystemExit(f"unknown attack {kind!r}")
    print(json.dumps(out), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
