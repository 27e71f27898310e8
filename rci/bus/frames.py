"""Sealed frames on the Zenoh link: a key agreed per connection, each publication encrypted and authenticated (MAC).

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

A sealed publication: ``counter (8 bytes, big endian) + ChaCha20-Poly1305(frame bytes)``
under the direction's key, the nonce made of the counter (never reused: the counter only
rises, and each direction has its own key), the counter authenticated as associated data:
the frame is encrypted (another process holding the same certificate reads nothing) and
carries a 16-byte message authentication code (Poly1305). The receiver drops (and counts,
by reason) a publication that is too short, too long, has a counter other than the next
one ("out of sequence": a replay, or garbage; checked first, so a flood of garbage costs
no decryption), or fails the code ("bad MAC"): a dropped publication
never reaches the link's frame decoder, so it can neither move the arm nor end the
owner's control.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass, field

COUNTER_BYTES = 8
TAG_BYTES = 16
OVERHEAD = COUNTER_BYTES + TAG_BYTES
MAX_SEALED = 2048 + OVERHEAD      # a frame of the link is at most ~1 KB (rci.protocol.MAX_PAYLOAD + header)
KEY_BYTES = 32


class KeyAgreementError(ValueError):
    """The other end's public key or hello cannot be used (says why)."""


def _aead(key: bytes):
    try:
        from cryptography.hazmat.primitives.ciphers.aead import ChaCha20Poly1305
    except ImportError:
        _crypto()
        raise
    return ChaCha20Poly1305(key)


def _nonce(counter: bytes) -> bytes:
    return b"\0\0\0\0" + counter


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


class Sealer:
    """Seals what one end publishes on its direction of a connection (counter + MAC)."""

    def __init__(self, key: bytes) -> None:
        self._aead = _aead(key)
        self._counter = 0
        self._lock = threading.Lock()

    def seal(self, frame: bytes) -> bytes:
        with self._lock:
            self._counter += 1
            counter = self._counter.to_bytes(COUNTER_BYTES, "big")
        return counter + self._aead.encrypt(_nonce(counter), frame, counter)


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


def _invalid_tag():
    from cryptography.exceptions import InvalidTag
    return InvalidTag


class Opener:
    """Checks what arrives on one direction of a connection; returns the frame bytes or None."""

    def __init__(self, key: bytes) -> None:
        self._aead = _aead(key)
        self._invalid = _invalid_tag()
        self._last = 0
        self.rejected = Rejections()

    def peek(self, sealed: bytes) -> bool:
        """Whether ``sealed`` is this direction's (a counter above the last one opened, the MAC
        right), changing and counting nothing: a cheap proof of the sender, for a queue that
        serves that sender first. A replay of a frame already opened does not pass."""
        if not OVERHEAD < len(sealed) <= MAX_SEALED:
            return False
        head = sealed[:COUNTER_BYTES]
        if int.from_bytes(head, "big") <= self._last:
            return False
        try:
            self._aead.decrypt(_nonce(head), sealed[COUNTER_BYTES:], head)
        except self._invalid:
            return False
        return True

    def open(self, sealed: bytes) -> bytes | None:
        n = len(sealed)
        if n < OVERHEAD + 1:
            self.rejected.add("too short")
            return None
        if n > MAX_SEALED:
            self.rejected.add("oversized")
            return None
        head = sealed[:COUNTER_BYTES]
        counter = int.from_bytes(head, "big")
        if counter != self._last + 1:      # the sealer counts 1, 2, 3 ... and Zenoh delivers in order:
            self.rejected.add("out of sequence")     # garbage and replays cost no decryption
            return None
        try:
            frame = self._aead.decrypt(_nonce(head), sealed[COUNTER_BYTES:], head)
        except self._invalid:
            self.rejected.add("bad MAC")
            return None
        self._last = counter
        return frame
