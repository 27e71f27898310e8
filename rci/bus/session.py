"""A Zenoh session of the project: the user's Zenoh configuration file plus the project's settings.

Every Zenoh-using command and API of the project opens its session here, so one Zenoh
configuration file (Zenoh's own JSON5 format: TLS, mutual TLS, user/password
authentication, access control, endpoints) applies to all of them (docs/security.md):

* an API's ``config=PATH`` argument, a link address's ``?config=PATH``, a command's
  ``--zenoh-config PATH``; else
* the environment variable ``RCI_ZENOH_CONFIG`` (a path); else
* no file: Zenoh's defaults.

On top of the file the project sets what its sessions must agree on: the mode (peer,
or the workcell's router and clients), multicast scouting off (endpoints are explicit,
so a session meets no stranger), Zenoh's low-latency transport without QoS lanes, and
the lease when one is asked for. Endpoints given by the caller replace the file's; without
either, a session listens or connects on loopback only (``DEFAULT_ENDPOINT``), or not at
all (a controller listens nowhere: Zenoh's own default would listen on every interface,
unauthenticated, and other peers told of it by gossip would connect to it directly).
"""
from __future__ import annotations

import json
import os
import socket

DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"
CONFIG_ENV = "RCI_ZENOH_CONFIG"


class ZenohLinkError(OSError):
    """The Zenoh link cannot be set up or has failed (says which key and why)."""


def free_endpoint(host: str = "127.0.0.1", scheme: str = "tcp") -> str:
    """A Zenoh locator on a port of ``host`` that is free now (``tcp/HOST:PORT``), for a
    session that listens: the OS picks the port, which is released for Zenoh to bind."""
    with socket.socket() as sock:
        sock.bind((host, 0))
        return f"{scheme}/{host}:{sock.getsockname()[1]}"


def config_path(config: str | os.PathLike | None = None) -> str | None:
    """The Zenoh configuration file to use: ``config``, else ``$RCI_ZENOH_CONFIG``, else None."""
    path = config if config is not None else os.environ.get(CONFIG_ENV) or None
    return None if path is None else os.fspath(path)


def load_config(config: str | os.PathLike | None = None):
    """A ``zenoh.Config`` read from the user's file (``config_path``), or Zenoh's defaults."""
    try:
        import zenoh
    except ImportError:
        raise ZenohLinkError("the Zenoh link needs the eclipse-zenoh package (pip install eclipse-zenoh)") from None
    path = config_path(config)
    if path is None:
        return zenoh.Config()
    if not os.path.isfile(path):
        raise ZenohLinkError(f"Zenoh configuration file {path!r} does not exist"
                             + (f" (from ${CONFIG_ENV})" if config is None else ""))
    try:
        return zenoh.Config.from_file(path)
    except Exception as exc:        # zenoh raises its own ZError: say which file and why
        raise ZenohLinkError(f"Zenoh configuration file {path!r} cannot be used: {exc}") from None


# Zenoh's own default for listen: every interface (a peer on a random port, a router on 7447):
# never the project's default, a session listens on loopback only or where it is told
_ZENOH_DEFAULT_LISTEN = {"router": ["tcp/[::]:7447"], "peer": ["tcp/[::]:0"]}


def configured_endpoints(conf, which: str) -> tuple[str, ...]:
    """The ``listen`` or ``connect`` endpoints a configuration file gives (empty if none;
    Zenoh's built-in default, every interface, does not count)."""
    try:
        value = json.loads(conf.get_json(f"{which}/endpoints"))
    except Exception:
        return ()
    if value == _ZENOH_DEFAULT_LISTEN:
        return ()
    if isinstance(value, dict):       # per-mode endpoints: {"router": [...], "peer": [...]}
        value = [e for v in value.values() for e in (v or [])]
    return tuple(str(e) for e in value or ())


def _threads() -> set[int]:
    try:
        return {int(t) for t in os.listdir("/proc/self/task")}
    except OSError:
        return set()


def undeclare(*objs) -> None:
    """Undeclare Zenoh publishers, subscribers, queryables and tokens, skipping None; a close
    path: one that fails (its session already closed) does not stop the others."""
    for obj in objs:
        if obj is None:
            continue
        try:
            obj.undeclare()
        except Exception:
            pass


def _realtime_threads(tids: set[int], priority: int) -> bool:
    """Run ``tids`` (Zenoh's runtime threads) under SCHED_FIFO ``priority`` where the OS
    allows: a frame crosses them on its way to and from the control thread, and a
    real-time control thread or simula's spin before a tick would otherwise keep them off
    the CPU for whole periods. False (nothing changed) without the privilege."""
    if priority <= 0 or not hasattr(os, "sched_setscheduler"):
        return False
    done = False
    for tid in tids:
        try:
            os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(priority))
            done = True
        except OSError:
            return done
    return done


def _json_list(items: tuple[str, ...]) -> str:
    return json.dumps(list(items))


def per_session_limit(rule_id: str, key_expr: str, per_s: float, messages: tuple[str, ...] = ("query",)) -> dict:
    """A Zenoh ``downsampling`` entry: at most ``per_s`` of ``messages`` a second on ``key_expr``
    from each Zenoh session connected to this one (ingress). Zenoh keeps the count per transport,
    that is per connected session, authenticated by its link (TLS): a sender cannot spend another
    session's share, whatever it writes into its messages (docs/security.md, "Fairness")."""
    return {"id": rule_id, "flows": ["ingress"], "messages": list(messages),
            "rules": [{"key_expr": key_expr, "freq": float(per_s)}]}


def _add_downsampling(conf, entries: tuple[dict, ...]) -> None:
    """Append ``entries`` to the file's ``downsampling`` list; an entry whose id the file
    already has is the file's (the user's word wins)."""
    if not entries:
        return
    try:
        present = json.loads(conf.get_json("downsampling")) or []
    except Exception:
        present = []
    ids = {e.get("id") for e in present if isinstance(e, dict)}
    conf.insert_json5("downsampling", json.dumps(present + [e for e in entries if e["id"] not in ids]))


def open_session(connect: tuple[str, ...] = (), listen: tuple[str, ...] = (), lease_ms: int | None = None,
                 priority: int = 0, router: bool = False, client: bool = False,
                 config: str | os.PathLike | None = None, default_connect: tuple[str, ...] = (),
                 default_listen: tuple[str, ...] = (), limits: tuple[dict, ...] = ()):
    """A Zenoh session: the user's configuration file (``config``, or ``$RCI_ZENOH_CONFIG``)
    with the project's settings on top (module docstring); its threads real-time at
    ``priority`` if > 0 and allowed. ``connect`` / ``listen`` replace the file's endpoints;
    ``default_connect`` / ``default_listen`` apply where neither gives any (loopback by the
    callers). ``router``: the session also routes between the sessions connected to it (the
    process the others connect to, in a workcell); ``client``: a client of such a router.
    ``limits``: per-session rate limits (``per_session_limit``) added to the file's."""
    import zenoh

    conf = load_config(config)
    conf.insert_json5("mode", '"router"' if router else ('"client"' if client else '"peer"'))
    conf.insert_json5("scouting/multicast/enabled", "false")
    for which, given, default in (("connect", connect, default_connect), ("listen", listen, default_listen)):
        # always set: what the caller gives, else the file's, else the default (loopback, or
        # none: a controller listens nowhere, where Zenoh's default listens on every interface)
        endpoints = given or configured_endpoints(conf, which) or default
        conf.insert_json5(f"{which}/endpoints", _json_list(endpoints))
    # the low-latency transport (no batching, no QoS lanes): about 30 % less round trip for the
    # link's small frames (measured: Python ping-pong between two processes on loopback, p50
    # 256 -> 181 us); every session of the link uses it, so peers agree
    conf.insert_json5("transport/unicast/lowlatency", "true")
    conf.insert_json5("transport/unicast/qos/enabled", "false")
    _add_downsampling(conf, tuple(limits))
    if lease_ms is not None:
        conf.insert_json5("transport/link/tx/lease", str(int(lease_ms)))
        conf.insert_json5("transport/link/tx/keep_alive", "4")
    before = _threads()
    try:
        session = zenoh.open(conf)
    except Exception as exc:    # zenoh raises its own ZError
        where = f", configuration {config_path(config)!r}" if config_path(config) else ""
        raise ZenohLinkError(f"cannot open a Zenoh session (connect {list(connect or default_connect)}, "
                             f"listen {list(listen or default_listen)}{where}): {exc}") from None
    _realtime_threads(_threads() - before, priority)
    return session
