"""The ``simula`` console script: start the simulated robot as a separate process (thesis A.7).

Usage (see docs/simula.md)::

    simula -p &                       # ready position, calibrated, real time, port 7600
    simula -c -v --lockstep --port 0  # nest, calibrated, lockstep, any free port, verbose
    simula --pty                      # serve a pseudo-terminal instead of TCP

stdout line 1 is the link address for ``rci.link.open_link`` (``socket://host:port`` or
the pty device path); line 2 is ``control socket://host:port`` (the control channel: state,
events, ping; the commands that act on the arm only with ``--test-channel``) unless
``--no-control``. With ``--view`` the next line is ``view http://127.0.0.1:PORT``: the arm
live in a browser (``rci.simula.view``; docs/viewer.md). With ``-v`` the joint angles
follow, once per simulated second.
"""
from __future__ import annotations

import argparse
import errno
import math
import signal
import sys
from contextlib import contextmanager
from dataclasses import replace
from typing import Iterator

from rcci.models import ModelError
from rcci.models import available_robots, load_robot
from ..rate import MAX_RATE_HZ, MIN_RATE_HZ
from .arm import SimulatedArm
from .control import ControlChannel
from .exceptions import SimulaError
from .params import load_params, parse_load, truth_from_model
from .server import LOCKSTEP_WATCHDOG_S, WATCHDOG_CYCLES, Server

DEFAULT_PORT = 7600
PORT_RANGE = (0, 65535)
PRIORITY_RANGE = (0, 99)          # SCHED_FIFO's on Linux; 0 leaves the scheduler alone
RATE_RANGE_HZ = (MIN_RATE_HZ, MAX_RATE_HZ)   # the one home of the rate range: rci.rate


def _integer(lo: int, hi: int | None = None, unit: str = ""):
    """An argparse ``type`` for an integer in lo..hi (hi None: no upper end); the message
    argparse prints names the option ("argument --port: ...") and this range."""
    span = (f"{lo}..{hi}" if hi is not None else f">= {lo}") + unit

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer (valid: {span})") from None
        if value < lo or (hi is not None and value > hi):
            raise argparse.ArgumentTypeError(f"{value} is out of range (valid: {span})")
        return value
    parse.__name__ = "integer"
    return parse


def _seconds(lo: float = 0.0):
    """An argparse ``type`` for a finite number of seconds >= lo."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds (valid: >= {lo:g})") from None
        if not math.isfinite(value) or value < lo:
            raise argparse.ArgumentTypeError(f"{text} s is out of range (valid: >= {lo:g} s)")
        return value
    parse.__name__ = "seconds"
    return parse


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="simula", description="RCI robot simulator (thesis A.7).")
    start = p.add_mutually_exclusive_group()
    start.add_argument("-p", dest="start", action="store_const", const="ready",
                       help="start in the ready position, calibrated")
    start.add_argument("-c", dest="start", action="store_const", const="nest",
                       help="start in the nest position, calibrated")
    p.add_argument("-v", "--verbose", action="store_true", help="print joint angles once per simulated second")
    p.add_argument("--robot", default="puma260",
                   help=f"robot model, a data file models/ROBOT.toml ({', '.join(available_robots())}) or its "
                        "path; default puma260")
    p.add_argument("--lockstep", action="store_true",
                   help="advance one period per CHG received (deterministic, as fast as possible)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default loopback only)")
    p.add_argument("--port", type=_integer(*PORT_RANGE), default=DEFAULT_PORT,
                   help=f"TCP port (default {DEFAULT_PORT}; 0 picks a free one, printed on line 1)")
    p.add_argument("--pty", action="store_true", help="serve a pseudo-terminal instead of TCP (path on line 1)")
    p.add_argument("--zenoh", metavar="KEY",
                   help="serve the arm on the Zenoh bus under rcci/KEY instead of TCP (link address "
                        "zenoh/KEY?connect=... on line 1; docs/zenoh.md)")
    p.add_argument("--zenoh-listen", metavar="ENDPOINT", action="append", default=[],
                   help="Zenoh endpoint to listen on (default tcp/127.0.0.1:7447; repeatable; another host's "
                        "controllers need an address they reach, and TLS with access control: docs/security.md)")
    p.add_argument("--zenoh-connect", metavar="ENDPOINT", action="append", default=[],
                   help="Zenoh endpoint (a router or a peer) to connect to (repeatable)")
    p.add_argument("--zenoh-config", metavar="FILE", default=None,
                   help="Zenoh configuration file (JSON5: TLS, authentication, access control; default "
                        "$RCI_ZENOH_CONFIG; `python -m rci.bus.keys` writes one per cell: docs/security.md)")
    p.add_argument("--control-port", type=_integer(*PORT_RANGE), default=0, help="control-channel port on loopback (0: any free)")
    p.add_argument("--no-control", action="store_true", help="no control channel")
    p.add_argument("--test-channel", action="store_true",
                   help="allow the control channel's commands that act on the arm (torque, load): tests only")
    p.add_argument("--seed", type=_integer(0), default=0, help="seed of every random disturbance (reproducible runs)")
    p.add_argument("--load", default="none", help="pulley load: pulley:joint=J,mass=KG,radius=M[,sign=+-1]")
    p.add_argument("--env", action="append", default=[], metavar="SPEC",
                   help="environment (repeatable): plane:z=..., box:..., conveyor:..., tool:z=... "
                        "(rci/simula/environment.py)")
    p.add_argument("--params", help="parameter file fitted by calib (schema rcci-calib-params/1)")
    p.add_argument("--dynamic", action="store_true",
                   help="couple current-mode joints through the full mass matrix and Coriolis terms")
    p.add_argument("--rate", type=_integer(*RATE_RANGE_HZ, unit=" Hz"), default=36,
                   help="sample rate announced before START (Hz, 4..1000; default 36)")
    p.add_argument("--watchdog", type=_integer(1), default=WATCHDOG_CYCLES,
                   help=f"real-time mode: missing CHGs in a row before the arm is stopped (>= 1; "
                        f"default {WATCHDOG_CYCLES})")
    p.add_argument("--watchdog-time", type=_seconds(), default=0.1,
                   help="real time: and at least this many seconds without a CHG (>= 0; default 0.1 s)")
    p.add_argument("--lockstep-watchdog", type=_seconds(), default=LOCKSTEP_WATCHDOG_S,
                   help=f"lockstep: wall-clock seconds without a CHG before a control is ended "
                        f"(default {LOCKSTEP_WATCHDOG_S}; 0: never)")
    p.add_argument("--priority", type=_integer(*PRIORITY_RANGE), default=70,
                   help="real time: SCHED_FIFO priority 1..99 (0: leave the scheduler alone); falls back quietly")
    p.add_argument("--warm", action="store_true", help="start with warmed-up joints (no cold friction excess)")
    p.add_argument("--power-on", action="store_true", help="start with arm power on")
    p.add_argument("--view", action="store_true",
                   help="show the arm live in a web browser (3D, with the --env surfaces): prints "
                        "'view http://127.0.0.1:PORT' after the control line (needs pip install 'rcci[view]')")
    p.add_argument("--view-port", type=_integer(*PORT_RANGE), default=8080,
                   help="the view's HTTP port (0..65535, default 8080; 0: any free one; a busy one: the next free)")
    return p


@contextmanager
def _naming_the_port(option: str, host: str, port: int) -> Iterator[None]:
    """A bind that fails says which option's port, and what to do when it is taken."""
    try:
        yield
    except OSError as exc:
        hint = (" (another simula, or another program, listens there: stop it or choose another "
                f"{option}; {option} 0 picks a free one)") if exc.errno == errno.EADDRINUSE else ""
        raise SimulaError(f"{option} {port}: cannot listen on {host}:{port}: {exc.strerror or exc}{hint}") from None


def _realtime_setup(server: Server, priority: int) -> None:
    """SCHED_FIFO, locked memory and a frozen GC for the real-time loop, where the OS allows."""
    import gc

    from ..realtime import RealtimeStatus, lock_memory, set_fifo
    status = RealtimeStatus()
    set_fifo(priority, status)
    lock_memory(status)
    gc.collect()
    gc.freeze()
    server.log(f"real-time set-up: SCHED_FIFO {status.sched_fifo}, mlockall {status.mlockall}")


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        model = load_robot(args.robot)
        truth = truth_from_model(model)
        if args.params:
            truth = load_params(args.params, model.name, truth)
        if args.warm:
            truth = replace(truth, disturbances=replace(truth.disturbances, start_warm=True))
        load = parse_load(args.load, model.n_joints)
        kw = dict(seed=args.seed, start=args.start or "uncalibrated", dynamic=args.dynamic, load=load)
        if args.env:
            from .environment import EnvironmentArm, parse_environment
            arm: SimulatedArm = EnvironmentArm(model, truth, environment=parse_environment(args.env), **kw)
        else:
            arm = SimulatedArm(model, truth, **kw)
        arm.power = bool(args.power_on)
        # every value was checked by the parser (build_parser): none is clamped here
        server = Server(arm, model.name, lockstep=args.lockstep, verbose=args.verbose, rate_hz=args.rate,
                        watchdog=args.watchdog, watchdog_time=args.watchdog_time,
                        lockstep_watchdog=args.lockstep_watchdog)
        if args.zenoh:
            from rci.bus.link import ZenohAddress
            url = server.listen("zenoh", address=ZenohAddress(args.zenoh.strip("/"), tuple(args.zenoh_connect),
                                                              tuple(args.zenoh_listen), config=args.zenoh_config),
                                # real time: Zenoh's threads just above the serving loop
                                priority=0 if args.lockstep or args.priority <= 0 else args.priority + 1)
        elif args.pty:
            url = server.listen("pty")
        else:
            with _naming_the_port("--port", args.host, args.port):
                url = server.listen("tcp", host=args.host, port=args.port)
        control = None
        if not args.no_control:
            with _naming_the_port("--control-port", "127.0.0.1", args.control_port):
                control = ControlChannel("127.0.0.1", args.control_port, test_commands=args.test_channel)
    except (ModelError, SimulaError, ValueError, OSError) as exc:
        print(f"simula: {exc}", file=sys.stderr)
        return 2
    view = None
    if args.view:   # before the real-time set-up: the view's process must not inherit SCHED_FIFO 70
        from ..view_link import ViewError
        from .view import start_view
        try:
            view = start_view(arm, model.name, args.env, port=args.view_port)
        except (ViewError, OSError) as exc:
            print(f"simula: --view: {exc}", file=sys.stderr)
            server.close()
            return 2
    print(url, flush=True)
    if control is not None:
        print(f"control {control.url}", flush=True)
    if view is not None:
        print(f"view {view.url}", flush=True)
    mode = "lockstep" if args.lockstep else "real time"
    server.log(f"{model.name} {args.start or 'uncalibrated'}, {mode}, seed {args.seed}, truth from {truth.source}")

    def _stop(signum, frame):  # noqa: ARG001 - signal handler signature
        raise SystemExit(0)

    if not args.lockstep and args.priority > 0:
        _realtime_setup(server, args.priority)
    signal.signal(signal.SIGTERM, _stop)
    signal.signal(signal.SIGINT, _stop)
    try:
        server.serve_forever(control)
    except SystemExit:
        pass
    finally:
        server.close()
        if view is not None:
            view.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
