"""A cell's certificate authority, keys and Zenoh configuration files: ``python -m rci.bus.keys``.

    python -m rci.bus.keys DIR --robot lab/puma260 --host 10.0.0.1 [--port 7447]

writes into DIR (docs/security.md):

* ``ca.pem`` / ``ca-key.pem``: the cell's certificate authority (keep ``ca-key.pem`` off
  the cell's hosts once the keys are made: whoever holds it can make identities);
* ``NAME.pem`` / ``NAME-key.pem`` for each identity, signed by the CA, its common name
  ``NAME`` (what the access control rules name) and, as subject alternative names,
  ``localhost`` and every ``--host``: ``robot`` (the robot's process, simula), ``controller``
  (the one process allowed to command the robot) and each ``--observer`` (members of the
  cell that may join the bus but not command the robot; ``observer`` by default);
* ``NAME.json5``: a Zenoh configuration file for that identity (``--zenoh-config`` /
  ``?config=`` / ``$RCI_ZENOH_CONFIG``): TLS with client certificates both ways (mutual
  TLS: a peer without a certificate of this CA is refused when its link opens), the robot's
  endpoint ``tls/HOST:PORT`` (listened on by ``robot``, connected to by the others), and in
  ``robot.json5`` the access control rules: by default nothing is allowed; ``controller``
  may ask for a connection and publish frames on the robot's command keys, and receive the
  robot's frames; other identities may do nothing on the robot's keys.

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

ROBOT, CONTROLLER = "robot", "controller"


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


def robot_acl(robots: list[str]) -> dict:
    """The robot's access control: deny by default; ``controller`` may use the link's keys."""
    keys = [f"rcci/{r}/{k}" for r in robots for k in ("hello", "robot", "c/**")]
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": [{"id": "robot link", "permission": "allow", "flows": ["ingress", "egress"],
                   "messages": ["put", "delete", "declare_subscriber", "query", "reply", "declare_queryable",
                                "liveliness_token", "liveliness_query", "declare_liveliness_subscriber"],
                   "key_exprs": keys}],
        "subjects": [{"id": "the controller", "cert_common_names": [CONTROLLER]}],
        "policies": [{"rules": ["robot link"], "subjects": ["the controller"]}],
    }


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


def make_cell(directory: str | os.PathLike, robots: list[str], hosts: list[str], port: int = 7447,
              observers: list[str] | None = None, days: int = 365, cell: str = "") -> dict[str, Path]:
    """Write a cell's CA, identities and configuration files; the configuration file of each identity."""
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    hosts = hosts or ["127.0.0.1"]
    ca_cert, ca_key = make_ca(out, cell or "/".join(robots), days)
    endpoint = f"tls/{hosts[0]}:{port}"
    written: dict[str, Path] = {}
    for name in [ROBOT, CONTROLLER, *(observers if observers is not None else ["observer"])]:
        make_identity(out, name, hosts, ca_cert, ca_key, days)
        conf = zenoh_config(out, name, endpoint, name == ROBOT, robot_acl(robots) if name == ROBOT else None)
        path = out / f"{name}.json5"
        path.write_text(json.dumps(conf, indent=2) + "\n")
        written[name] = path
    return written


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m rci.bus.keys", description=__doc__.split("\n\n")[0])
    ap.add_argument("directory", help="where to write the CA, the keys and the configuration files")
    ap.add_argument("--robot", action="append", required=True, metavar="KEY",
                    help="the robot's key on the bus (simula --zenoh KEY; repeatable)")
    ap.add_argument("--host", action="append", default=[], metavar="ADDRESS",
                    help="the robot's host address (the first is the endpoint; each goes into the certificates; "
                         "default 127.0.0.1)")
    ap.add_argument("--port", type=int, default=7447, help="the robot's TLS port (default 7447)")
    ap.add_argument("--observer", action="append", default=None, metavar="NAME",
                    help="an identity that may join the bus but not command the robot (default: observer)")
    ap.add_argument("--days", type=int, default=365, help="validity of the certificates (days)")
    a = ap.parse_args(argv)
    for name in a.observer or []:
        if name in (ROBOT, CONTROLLER) or not name.replace("-", "").isalnum():
            ap.error(f"--observer {name!r}: a plain name other than {ROBOT!r} and {CONTROLLER!r}")
    written = make_cell(a.directory, [r.strip("/") for r in a.robot], a.host, a.port, a.observer, a.days)
    for name, path in written.items():
        print(f"{name}: {path}")
    print(f"keep {Path(a.directory) / 'ca-key.pem'} off the cell's hosts (docs/security.md)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
