"""Authenticated frames on the Zenoh link: a key agreed per connection, a MAC on every publication.

Zenoh's TLS and access control (docs/security.md) decide which processes may join the bus
and which keys each may publish on. This module is the defence behind them: on a
connection of the robot link, a publication counts only if it was made by the end of the
connection that agreed its key, whatever identity the publisher has on the bus.

Key agreement (at the connection's hello query, before any frame): each end makes an
ephemeral X25519 key pair; the controller sends its public key with its connection id,
the robot answers with its own; both derive, with HKDF-SHA256 over the shared secret
(salted with both public keys, bound to the robot's key expression and the connection
id), one 32-byte key per direction. Nobody who only reads the hello (or every later
publication) learns them.

A sealed publication: ``counter (8 bytes, big endian) + frame bytes + tag (16 bytes)``,
the tag the first 16 bytes of HMAC-SHA256(direction key, counter + frame bytes). The
receiver drops (and counts, by reason) one that is too short, too long, has a wrong tag,
or a counter not above the last accepted (a replay or a reordering): a dropped
publication never reaches the link's frame decoder, so it can neither move the arm nor
end the owner's control.
"""
from __future__ import annotations

import hmac
import threading
from dataclasses import dataclass, field

COUNTER_BYTES = 8
TAG_BYTES = 16
OVERHEAD = COUNTER_BYTES + TAG_BYTES
MAX_SEALED = 2048 + OVERHEAD      # a frame of the link is at most ~1 KB (rci.protocol.MAX_PAYLOAD + header)
KEY_BYTES = 32


class KeyAgreementError(ValueError):
    """The other end's public key or hello cannot be used (says why)."""


def _crypto():
    try:
        from cryptography.hazmat.primitives import hashes, serialization
        from cryptography.hazmat.primitives.asymmetric.x25519 import X25519PrivateKey, X25519PublicKey
        from cryptography.hazmat.primitives.kdf.hkdf import HKDF
    except ImportError:
        raise KeyAgreementError("the Zenoh link's frame authentication needs the cryptography package "
                                "(pip install 'rcci[zenoh]' or pip install cryptography)") from None
    return hashes, serialization, X25519PrivateKey, X25519PublicKey, HKDF


class Handshake:
    """One end's ephemeral X25519 key pair; :meth:`keys` derives the two direction keys."""

    def __init__(self) -> None:
        _, serialization, private_cls, _, _ = _crypto()
        self._private = private_cls.generate()
        self.public = self._private.public_key().public_bytes(serialization.Encoding.Raw,
                                                              serialization.PublicFormat.Raw)

    def keys(self, peer_public: bytes, controller_public: bytes, robot_public: bytes,
             context: str) -> tuple[bytes, bytes]:
        """(controller -> robot key, robot -> controller key) for this connection."""
        hashes, _, _, public_cls, hkdf_cls = _crypto()
        if len(peer_public) != KEY_BYTES:
            raise KeyAgreementError(f"a public key of {len(peer_public)} bytes (X25519 has {KEY_BYTES})")
        try:
            shared = self._private.exchange(public_cls.from_public_bytes(peer_public))
        except ValueError as exc:
            raise KeyAgreementError(f"unusable public key: {exc}") from None
        okm = hkdf_cls(algorithm=hashes.SHA256(), length=2 * KEY_BYTES, salt=controller_public + robot_public,
                       info=b"rcci zenoh link v1 " + context.encode()).derive(shared)
        return okm[:KEY_BYTES], okm[KEY_BYTES:]


def _tag(key: bytes, counter_and_frame: bytes) -> bytes:
    return hmac.digest(key, counter_and_frame, "sha256")[:TAG_BYTES]


class Sealer:
    """Seals what one end publishes on its direction of a connection (counter + MAC)."""

    def __init__(self, key: bytes) -> None:
        self._key = key
        self._counter = 0
        self._lock = threading.Lock()

    def seal(self, frame: bytes) -> bytes:
        with self._lock:
            self._counter += 1
            body = self._counter.to_bytes(COUNTER_BYTES, "big") + frame
        return body + _tag(self._key, body)


@dataclass
class Rejections:
    """Publications an end dropped, by reason (read by the robot's log and the tests)."""

    counts: dict[str, int] = field(default_factory=dict)

    def add(self, reason: str) -> None:
        self.counts[reason] = self.counts.get(reason, 0) + 1

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def describe(self) -> str:
        return ", ".join(f"{n} {why}" for why, n in sorted(self.counts.items())) or "none"


class Opener:
    """Checks what arrives on one direction of a connection; returns the frame bytes or None."""

    def __init__(self, key: bytes) -> None:
        self._key = key
        self._last = 0
        self.rejected = Rejections()

    def open(self, sealed: bytes) -> bytes | None:
        n = len(sealed)
        if n < OVERHEAD + 1:
            self.rejected.add("too short")
            return None
        if n > MAX_SEALED:
            self.rejected.add("oversized")
            return None
        body, tag = sealed[:-TAG_BYTES], sealed[-TAG_BYTES:]
        if not hmac.compare_digest(_tag(self._key, body), tag):
            self.rejected.add("bad MAC")
            return None
        counter = int.from_bytes(body[:COUNTER_BYTES], "big")
        if counter <= self._last:
            self.rejected.add("replayed")
            return None
        self._last = counter
        return body[COUNTER_BYTES:]
