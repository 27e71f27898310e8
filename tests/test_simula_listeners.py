"""simula's endpoints (rci.simula.listeners): found by name, each hands the server byte pipes.

Real sockets and a real pseudo-terminal; the whole simula over each is in
test_simula_process.py, test_rci_simula.py and test_zenoh.py."""
from __future__ import annotations

import os
import select
import socket
import time

import pytest

from rci.simula import listeners
from rci.simula.listeners import UnknownListener, open_listener
from rci.simula.listeners.pty import PtyTransport
from rci.simula.listeners.tcp import SocketTransport


def test_every_listener_is_found_by_name_and_mirrors_a_transport():
    assert listeners.kinds() == {"tcp": "tcp", "pty": "pty", "zenoh": "zenoh"}
    from rci.simula.listeners import tcp, zenoh
    from rci.transports import tcp as tcp_transport, zenoh as zenoh_transport
    # the two sides of a link speak of the same address
    assert tcp.SCHEME == tcp_transport.SCHEME and zenoh.SCHEME == zenoh_transport.SCHEME


def test_an_unknown_listener_is_refused_naming_the_known_ones():
    with pytest.raises(UnknownListener, match=r"no simula listener 'udp' \(known: pty, tcp, zenoh\)"):
        open_listener("udp")


def _accept_within(listener, seconds: float = 5.0):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        select.select([listener], [], [], 0.1)
        got = listener.accept()
        if got:
            return got
    raise AssertionError("no connection accepted")


def test_tcp_accepts_a_connection_and_moves_bytes_both_ways():
    lis = open_listener("tcp", host="127.0.0.1", port=0)
    try:
        assert lis.line is None and lis.url.startswith("socket://127.0.0.1:")
        port = int(lis.url.rsplit(":", 1)[1])
        assert lis.accept() == []                       # nobody yet: never blocks
        with socket.create_connection(("127.0.0.1", port), timeout=5) as peer:
            [conn] = _accept_within(lis)
            assert isinstance(conn, SocketTransport) and conn.address.startswith("127.0.0.1:")
            assert conn.write(b"HOW")
            assert peer.recv(16) == b"HOW"
            peer.sendall(b"CHG")
            select.select([conn], [], [], 5)
            assert conn.read() == b"CHG"
            peer.close()
            select.select([conn], [], [], 5)
            assert conn.read() is None                  # end of file: the controller is gone
            conn.close()
    finally:
        lis.close()


def test_a_busy_tcp_port_raises_oserror_and_leaves_no_socket_open():
    lis = open_listener("tcp", host="127.0.0.1", port=0)
    try:
        port = int(lis.url.rsplit(":", 1)[1])
        before = len(os.listdir("/proc/self/fd"))
        with pytest.raises(OSError):
            open_listener("tcp", host="127.0.0.1", port=port)
        assert len(os.listdir("/proc/self/fd")) == before
    finally:
        lis.close()


def test_a_pty_is_one_line_there_from_the_start():
    lis = open_listener("pty")
    try:
        assert isinstance(lis.line, PtyTransport)
        assert lis.url == lis.line.path and lis.url.startswith("/dev/")
        assert lis.fileno() is None and lis.accept() == []
        fd = os.open(lis.url, os.O_RDWR | os.O_NOCTTY)
        try:
            os.write(fd, b"HELLO")
            select.select([lis.line], [], [], 5)
            assert lis.line.read() == b"HELLO"
            assert lis.line.write(b"WELCOME")
            assert os.read(fd, 16) == b"WELCOME"
        finally:
            os.close(fd)
        assert lis.line.read() == b""                   # a pty has no end of file: the line stays
    finally:
        lis.close()
