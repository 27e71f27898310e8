"""A cell's certificate authority, keys and Zenoh configuration files: ``python -m rci.bus.keys``.

    python -m rci.bus.keys DIR --robot lab/puma260 --host 10.0.0.1 [--port 7447]
    python -m rci.bus.keys DIR --cell lab --task puma --task microbo [--shared NAME=TASK] [--bus-host H]

writes into DIR (docs/security.md):

* ``ca.pem`` / ``ca-key.pem``: the cell's certificate authority (keep ``ca-key.pem`` off
  the cell's hosts once the keys are made: whoever holds it can make identities);
* ``NAME.pem`` / ``NAME-key.pem`` for each identity, signed by the CA, its common name
  ``NAME`` (what the access control rules name) and, as subject alternative names,
  ``localhost`` and every ``--host`` (and ``--bus-host``): for the robot link (``--robot``),
  ``robot`` (the robot's process, simula) and ``controller`` (the one process allowed to
  command the robot); for the workcell's bus (``--cell``), the planning level (``--planner``,
  ``planning`` by default: the bus's hub) and each ``--task`` (an arm process's name, or a
  task of rci.bus.Bus); each ``--observer`` (members of the cell that may read but command
  and write nothing; ``observer`` by default);
* ``NAME.json5``: a Zenoh configuration file of that identity for the robot link
  (``--zenoh-config`` / ``?config=`` / ``$RCI_ZENOH_CONFIG``): TLS with client certificates
  both ways (mutual TLS: a peer without a certificate of this CA is refused when its link
  opens), the robot's endpoint ``tls/HOST:PORT`` (listened on by ``robot``, connected to by
  the others), and in ``robot.json5`` the access control rules: by default nothing is
  allowed; ``controller`` may ask for a connection and publish frames on the robot's
  command keys, and receive the robot's frames; other identities may do nothing on them;
* ``bus-NAME.json5``: the same for the workcell's bus: the hub listens at
  ``tls/BUS_HOST:BUS_PORT`` with the workcell's access control (``workcell_acl``: every member
  reads the cell's keys, each key is written only by its writer), the others connect there.

Elliptic-curve keys (P-256), certificates valid ``--days`` (365 by default); the private
keys are written with mode 0600.
"""
from __future__ import annotations

import argparse
import datetime
import ipaddress
import json
import os
import sys
from pathlib import Path

ROBOT, CONTROLLER, PLANNER = "robot", "controller", "planning"


def _x509():
    try:
        from cryptography import x509
        from cryptography.hazmat.primitives import hashes, serialization
        from cryptography.hazmat.primitives.asymmetric import ec
        from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID
    except ImportError:
        raise SystemExit("python -m rci.bus.keys needs the cryptography package (pip install 'rcci[zenoh]')") from None
    return x509, hashes, serialization, ec, ExtendedKeyUsageOID, NameOID


def _write_key(path: Path, key) -> None:
    _, _, serialization, _, _, _ = _x509()
    data = key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                             serialization.NoEncryption())
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as f:
        f.write(data)


def _write_cert(path: Path, cert) -> None:
    _, _, serialization, _, _, _ = _x509()
    path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))


def make_ca(directory: Path, cell: str, days: int):
    """The cell's CA: (certificate, private key), written as ca.pem and ca-key.pem."""
    x509, hashes, _, ec, _, NameOID = _x509()
    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, f"rcci cell {cell} CA")])
    now = datetime.datetime.now(datetime.timezone.utc)
    cert = (x509.CertificateBuilder().subject_name(name).issuer_name(name).public_key(key.public_key())
            .serial_number(x509.random_serial_number()).not_valid_before(now - datetime.timedelta(minutes=5))
            .not_valid_after(now + datetime.timedelta(days=days))
            .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
            .add_extension(x509.KeyUsage(digital_signature=False, content_commitment=False, key_encipherment=False,
                                         data_encipherment=False, key_agreement=False, key_cert_sign=True,
                                         crl_sign=True, encipher_only=False, decipher_only=False), critical=True)
            .sign(key, hashes.SHA256()))
    _write_cert(directory / "ca.pem", cert)
    _write_key(directory / "ca-key.pem", key)
    return cert, key


def make_identity(directory: Path, name: str, hosts: list[str], ca_cert, ca_key, days: int) -> None:
    """NAME.pem / NAME-key.pem: common name NAME, valid as a TLS server and client for ``hosts``."""
    x509, hashes, _, ec, EKU, NameOID = _x509()
    key = ec.generate_private_key(ec.SECP256R1())
    alt: list = [x509.DNSName("localhost")]
    for h in hosts:
        try:
            alt.append(x509.IPAddress(ipaddress.ip_address(h)))
        except ValueError:
            alt.append(x509.DNSName(h))
    now = datetime.datetime.now(datetime.timezone.utc)
    cert = (x509.CertificateBuilder().subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)]))
            .issuer_name(ca_cert.subject).public_key(key.public_key()).serial_number(x509.random_serial_number())
            .not_valid_before(now - datetime.timedelta(minutes=5)).not_valid_after(now + datetime.timedelta(days=days))
            .add_extension(x509.SubjectAlternativeName(alt), critical=False)
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .add_extension(x509.ExtendedKeyUsage([EKU.SERVER_AUTH, EKU.CLIENT_AUTH]), critical=False)
            .sign(ca_key, hashes.SHA256()))
    _write_cert(directory / f"{name}.pem", cert)
    _write_key(directory / f"{name}-key.pem", key)


_MESSAGES = ["put", "delete", "declare_subscriber", "query", "reply", "declare_queryable", "liveliness_token",
             "liveliness_query", "declare_liveliness_subscriber"]


def robot_acl(robots: list[str]) -> dict:
    """The robot's access control: deny by default; ``controller`` may use the link's keys."""
    keys = [f"rcci/{r}/{k}" for r in robots for k in ("hello", "robot", "c/**")]
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": [{"id": "robot link", "permission": "allow", "flows": ["ingress", "egress"],
                   "messages": list(_MESSAGES), "key_exprs": keys}],
        "subjects": [{"id": "the controller", "cert_common_names": [CONTROLLER]}],
        "policies": [{"rules": ["robot link"], "subjects": ["the controller"]}],
    }


def _allow(rule_id: str, flows: list[str], messages: list[str], keys: list[str]) -> dict:
    return {"id": rule_id, "permission": "allow", "flows": flows, "messages": messages, "key_exprs": keys}


def task_writes(cell: str, task: str, shared: list[str]) -> dict[str, list[str]]:
    """What task ``task`` (an arm process, or any task of rci.bus.Bus) may say on the workcell's
    bus, by message kind: its channels as sender (``channel/TASK/*``) and as receiver (the
    acknowledgements ``channel/*/TASK/ack``), the shared values it owns (``shared``), and an
    arm process's keys under its name (``arm/TASK/...``, ``flags/TASK/...``: rccl.bus.wire)."""
    c = f"rcci/{cell}"
    values = [f"{c}/shared/{name}" for name in shared]
    return {"put": [f"{c}/channel/{task}/*", f"{c}/channel/*/{task}/ack", f"{c}/arm/{task}/*", f"{c}/flags/{task}/*",
                    *values],
            "declare_queryable": [f"{c}/arm/{task}/request", f"{c}/flags/{task}/*", f"{c}/shared/*"],
            "reply": [f"{c}/arm/{task}/request", f"{c}/flags/{task}/*", *values],
            "liveliness_token": [f"{c}/arm/{task}"]}


def planner_writes(cell: str) -> dict[str, list[str]]:
    """What the planning level may say beyond a task's: start_ev / stop_ev (``flags/set``), its
    heartbeat and token (``planner/...``) and requests to the arm processes (``arm/*/request``)."""
    c = f"rcci/{cell}"
    return {"put": [f"{c}/flags/set", f"{c}/planner/*/alive"], "liveliness_token": [f"{c}/planner/*"],
            "query": [f"{c}/arm/*/request"]}


def workcell_acl(cell: str, planner: str, tasks: list[str], observers: list[str],
                 shared: dict[str, list[str]]) -> dict:
    """The workcell bus's access control, for its hub (the process the others connect to, which
    routes between them: rci.bus.Bus): deny by default; every member of the cell (the planning
    level, the tasks, the observers) may read the cell's keys (subscribe, query shared values
    and flags, see tokens); only the writer each key has may write it (``task_writes``,
    ``planner_writes``: a shared value by the tasks ``shared`` names for it). A member's
    message it may not send is dropped by the hub where it comes in."""
    c = f"rcci/{cell}"
    members = [planner, *tasks, *observers]
    rules = [_allow("cell: to every member", ["egress"], list(_MESSAGES), [f"{c}/**"]),
             _allow("cell: read", ["ingress"], ["declare_subscriber", "declare_liveliness_subscriber",
                                                "liveliness_query"], [f"{c}/**"]),
             _allow("cell: ask shared values and flags", ["ingress"], ["query"], [f"{c}/shared/*", f"{c}/flags/*/*"])]
    subjects = [{"id": "cell: members", "cert_common_names": members}]
    policies = [{"rules": [r["id"] for r in rules], "subjects": ["cell: members"]}]
    for task in [planner, *tasks]:
        writes = task_writes(cell, task, [name for name, who in shared.items() if task in who])
        if task == planner:
            for kind, keys in planner_writes(cell).items():
                writes[kind] = writes.get(kind, []) + keys
        ids = []
        for kind, keys in writes.items():
            rules.append(_allow(f"{task}: {kind}", ["ingress"], [kind], keys))
            ids.append(rules[-1]["id"])
        subjects.append({"id": f"task {task}", "cert_common_names": [task]})
        policies.append({"rules": ids, "subjects": [f"task {task}"]})
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects, "policies": policies}


def zenoh_config(directory: Path, name: str, endpoint: str, listen: bool, acl: dict | None) -> dict:
    """The Zenoh configuration of identity ``name``: mutual TLS with the cell's CA."""
    d = directory.resolve()
    tls = {"root_ca_certificate": str(d / "ca.pem"), "enable_mtls": True, "verify_name_on_connect": True,
           "listen_private_key": str(d / f"{name}-key.pem"), "listen_certificate": str(d / f"{name}.pem"),
           "connect_private_key": str(d / f"{name}-key.pem"), "connect_certificate": str(d / f"{name}.pem")}
    conf: dict = {"transport": {"link": {"tls": tls}}}
    conf["listen" if listen else "connect"] = {"endpoints": [endpoint]}
    if acl is not None:
        conf["access_control"] = acl
    return conf


def _write_json(path: Path, conf: dict) -> Path:
    path.write_text(json.dumps(conf, indent=2) + "\n")
    return path


def make_cell(directory: str | os.PathLike, robots: list[str], hosts: list[str], port: int = 7447,
              observers: list[str] | None = None, days: int = 365, cell: str = "", workcell: str | None = None,
              tasks: list[str] | None = None, planner: str = PLANNER, shared: dict[str, list[str]] | None = None,
              bus_host: str | None = None, bus_port: int = 7448) -> dict[str, Path]:
    """Write a cell's CA, identities and configuration files; the configuration file of each
    identity: ``NAME`` for the robot link (``robots``), ``bus NAME`` for the workcell's bus
    (``workcell``: its hub ``planner`` listens at ``tls/BUS_HOST:BUS_PORT``, with the workcell's
    access control; the ``tasks`` and the observers connect there)."""
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    hosts = hosts or ["127.0.0.1"]
    observers = observers if observers is not None else ["observer"]
    tasks = list(tasks or [])
    names = ([ROBOT, CONTROLLER] if robots else []) + observers
    if workcell:
        names += [planner, *tasks]
    if len(set(names)) != len(names):
        raise ValueError(f"identities must have distinct names, got {names}")
    ca_cert, ca_key = make_ca(out, cell or workcell or "/".join(robots), days)
    bus_host = bus_host or hosts[0]
    for name in dict.fromkeys(names):
        make_identity(out, name, hosts + ([bus_host] if bus_host not in hosts else []), ca_cert, ca_key, days)
    written: dict[str, Path] = {}
    if robots:
        endpoint = f"tls/{hosts[0]}:{port}"
        for name in [ROBOT, CONTROLLER, *observers]:
            conf = zenoh_config(out, name, endpoint, name == ROBOT, robot_acl(robots) if name == ROBOT else None)
            written[name] = _write_json(out / f"{name}.json5", conf)
    if workcell:
        endpoint = f"tls/{bus_host}:{bus_port}"
        acl = workcell_acl(workcell, planner, tasks, observers, shared or {})
        for name in [planner, *tasks, *observers]:
            conf = zenoh_config(out, name, endpoint, name == planner, acl if name == planner else None)
            written[f"bus {name}"] = _write_json(out / f"bus-{name}.json5", conf)
    return written


def _plain(ap: argparse.ArgumentParser, option: str, name: str) -> str:
    if name in (ROBOT, CONTROLLER) or not name.replace("-", "").replace("_", "").isalnum():
        ap.error(f"{option} {name!r}: a plain name other than {ROBOT!r} and {CONTROLLER!r}")
    return name


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m rci.bus.keys", description=__doc__.split("\n\n")[0])
    ap.add_argument("directory", help="where to write the CA, the keys and the configuration files")
    ap.add_argument("--robot", action="append", default=[], metavar="KEY",
                    help="the robot's key on the bus (simula --zenoh KEY; repeatable)")
    ap.add_argument("--host", action="append", default=[], metavar="ADDRESS",
                    help="the robot's host address (the first is the endpoint; each goes into the certificates; "
                         "default 127.0.0.1)")
    ap.add_argument("--port", type=int, default=7447, help="the robot's TLS port (default 7447)")
    ap.add_argument("--observer", action="append", default=None, metavar="NAME",
                    help="an identity that may join the bus but not command the robot (default: observer)")
    ap.add_argument("--cell", metavar="NAME", default=None,
                    help="the workcell's name on its bus (rci.bus.Bus, rccl.bus): write its access control too")
    ap.add_argument("--planner", metavar="NAME", default=PLANNER,
                    help=f"the planning level's identity, the workcell bus's hub (default {PLANNER})")
    ap.add_argument("--task", action="append", default=[], metavar="NAME",
                    help="a task of the workcell (an arm process's name, or a task of rci.bus.Bus; repeatable)")
    ap.add_argument("--shared", action="append", default=[], metavar="NAME=TASK[,TASK]",
                    help="a shared value of the workcell and the tasks that may write it (repeatable)")
    ap.add_argument("--bus-host", metavar="ADDRESS", default=None,
                    help="the hub's host address (default the first --host)")
    ap.add_argument("--bus-port", type=int, default=7448, help="the hub's TLS port (default 7448)")
    ap.add_argument("--days", type=int, default=365, help="validity of the certificates (days)")
    a = ap.parse_args(argv)
    if not a.robot and not a.cell:
        ap.error("say what to secure: --robot KEY (the robot link) and/or --cell NAME (the workcell's bus)")
    for name in a.observer or []:
        _plain(ap, "--observer", name)
    for name in [a.planner, *a.task]:
        _plain(ap, "--task" if name != a.planner else "--planner", name)
    shared: dict[str, list[str]] = {}
    for item in a.shared:
        value, _, who = item.partition("=")
        writers = [w for w in who.split(",") if w]
        if not value or any(c in value for c in "/*$#? ") or not writers:
            ap.error(f"--shared {item!r}: NAME=TASK[,TASK] (a shared value's name and who may write it)")
        unknown = [w for w in writers if w not in (a.planner, *a.task)]
        if unknown:
            ap.error(f"--shared {item!r}: {', '.join(unknown)} is not the planner nor a --task")
        shared[value] = writers
    try:
        written = make_cell(a.directory, [r.strip("/") for r in a.robot], a.host, a.port, a.observer, a.days,
                            workcell=a.cell, tasks=a.task, planner=a.planner, shared=shared, bus_host=a.bus_host,
                            bus_port=a.bus_port)
    except ValueError as exc:
        ap.error(str(exc))
    for name, path in written.items():
        print(f"{name}: {path}")
    print(f"keep {Path(a.directory) / 'ca-key.pem'} off the cell's hosts (docs/security.md)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
