"""The bus's security parts on their own (rci.bus.frames, guard, session, keys) and over loopback.

The attacks themselves, between network namespaces, are in tests/test_security_netns.py.
"""
from __future__ import annotations

import json
import os
import stat
import threading
import time
from contextlib import ExitStack

import pytest

from rci.bus.frames import OVERHEAD, Handshake, KeyAgreementError, Opener, Sealer
from rci.bus.guard import BoundedWorker, Episodes, Lanes, TokenBucket
from rci.bus.keys import make_cell
from rci.bus.link import ZenohAddress
from rci.bus.session import CONFIG_ENV, ZenohLinkError, configured_endpoints, load_config, open_session


def _pair() -> tuple[tuple[bytes, bytes], tuple[bytes, bytes]]:
    """Both ends' (down, up) keys after one key agreement."""
    ctl, rob = Handshake(), Handshake()
    return (ctl.keys(rob.public, ctl.public, rob.public, "rcci/t/c/1"),
            rob.keys(ctl.public, ctl.public, rob.public, "rcci/t/c/1"))


def test_both_ends_agree_one_key_per_direction_and_nobody_else_does():
    (c_down, c_up), (r_down, r_up) = _pair()
    assert (c_down, c_up) == (r_down, r_up) and c_down != c_up and len(c_down) == 32
    (o_down, _), _ = _pair()                     # another connection: other keys
    assert o_down != c_down
    with pytest.raises(KeyAgreementError, match="public key of 5 bytes"):
        Handshake().keys(b"short", b"", b"", "x")


def test_a_sealed_frame_opens_once_and_anything_else_is_dropped_and_counted():
    (down, _), _ = _pair()
    sealer, opener = Sealer(down), Opener(down)
    frames = [bytes([i]) * (10 + i) for i in range(5)]
    sealed = [sealer.seal(f) for f in frames]
    assert all(f not in s for f, s in zip(frames, sealed))       # encrypted, not only signed
    assert [opener.open(s) for s in sealed] == frames
    assert opener.open(sealed[2]) is None                        # replayed: out of sequence
    assert opener.open(b"\xA5\x5A" + bytes(40)) is None          # garbage, a bare forged frame: out of sequence
    nxt = sealer.seal(b"\xA5\x5A a CHG")                         # the owner's next frame (counter 6) ...
    tampered = bytearray(nxt)
    tampered[12] ^= 1
    assert opener.open(bytes(tampered)) is None                  # ... one bit changed: bad MAC
    forged = (6).to_bytes(8, "big") + Sealer(os.urandom(32)).seal(b"x")[8:]
    assert opener.open(forged) is None                           # the right counter, another key: bad MAC
    assert opener.open(nxt[:OVERHEAD]) is None                   # truncated
    assert opener.open(bytes(5000)) is None                      # oversized
    assert opener.rejected.counts == {"out of sequence": 2, "bad MAC": 2, "too short": 1, "oversized": 1}
    assert opener.open(nxt) == b"\xA5\x5A a CHG"                  # the owner's frames go on
    assert opener.open(sealer.seal(b"still")) == b"still"


def test_a_peek_proves_the_sender_without_using_up_its_frame():
    (down, _), _ = _pair()
    sealer, opener = Sealer(down), Opener(down)
    first, second = sealer.seal(b"one"), sealer.seal(b"two")
    assert opener.peek(second) and opener.peek(first)             # both still to come, both the sender's
    assert opener.open(first) == b"one" and not opener.peek(first)     # once opened, a replay does not pass
    assert not opener.peek(first[:8] + bytes(len(first) - 8)) and not opener.peek(b"short")
    assert not opener.peek((5).to_bytes(8, "big") + Sealer(os.urandom(32)).seal(b"x")[8:])   # another key
    assert opener.rejected.total == 0 and opener.open(second) == b"two"     # peeking counted and changed nothing


def test_the_first_lane_goes_ahead_of_a_flood_in_the_other():
    lanes = Lanes(2, 4)
    assert [lanes.offer(i) for i in range(100)] == [True] * 4 + [False] * 96      # a flood: 4 kept
    assert lanes.offer("holder", first=True) and lanes.offer("holder 2", first=True)
    assert not lanes.offer("holder 3", first=True) and lanes.dropped == 97
    assert [lanes.take(0.1) for _ in range(7)] == ["holder", "holder 2", 0, 1, 2, 3, None]


def test_a_token_bucket_allows_its_rate():
    bucket = TokenBucket(rate=100.0, burst=5)
    assert sum(bucket.take() for _ in range(50)) == 5             # the burst, then nothing at once
    time.sleep(0.1)
    assert 5 <= sum(bucket.take() for _ in range(50)) <= 15       # ~10 more after 0.1 s


def test_a_bounded_worker_drops_what_does_not_fit_and_counts_it():
    done: list[int] = []
    gate = threading.Event()
    worker = BoundedWorker("test", lambda i: (gate.wait(5), done.append(i)), capacity=4, rate=1000.0)
    try:
        offered = [worker.offer(i) for i in range(100)]
        assert sum(offered) <= 5 and worker.dropped >= 95          # one may already be taken by the thread
        gate.set()
        deadline = time.monotonic() + 5
        while len(done) < sum(offered) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert len(done) == sum(offered) and worker.offered == 100
    finally:
        worker.close()


def test_a_flood_is_reported_once_with_its_count():
    n = [0]
    ep = Episodes("test", lambda: n[0], lambda: "garbage", quiet_s=0.5)
    t = 100.0
    assert ep.poll(t) is None
    for k in range(1, 40):                     # 3,900 rejected over 3.9 s
        n[0] = 100 * k
        assert ep.poll(t + 0.1 * k) is None
    assert ep.poll(t + 4.0) is None            # not quiet for long enough yet
    line = ep.poll(t + 4.5)
    assert line == "test: 3900 rejected over 3.8 s (total 3900: garbage)"
    assert ep.poll(t + 10.0) is None and ep.lines == [line]


def test_a_user_configuration_file_is_read_and_a_missing_one_named(tmp_path, monkeypatch):
    conf = tmp_path / "cell.json5"
    conf.write_text('{ // a comment: JSON5\n connect: { endpoints: ["tls/10.0.0.1:7447"] } }\n')
    assert configured_endpoints(load_config(conf), "connect") == ("tls/10.0.0.1:7447",)
    assert configured_endpoints(load_config(None), "listen") == ()     # Zenoh's every-interface default is not taken
    monkeypatch.setenv(CONFIG_ENV, str(conf))
    assert configured_endpoints(load_config(None), "connect") == ("tls/10.0.0.1:7447",)
    monkeypatch.setenv(CONFIG_ENV, str(tmp_path / "nope.json5"))
    with pytest.raises(ZenohLinkError, match=r"nope.json5' does not exist \(from \$RCI_ZENOH_CONFIG\)"):
        load_config(None)
    bad = tmp_path / "bad.json5"
    bad.write_text("{ mode: ")
    with pytest.raises(ZenohLinkError, match="bad.json5' cannot be used"):
        load_config(bad)
    a = ZenohAddress.parse(f"zenoh/lab/puma?config={conf}")
    assert a.config == str(conf) and ZenohAddress.parse(a.url()) == a


def test_a_per_session_limit_is_added_to_the_files_and_the_files_own_wins(tmp_path):
    from rci.bus.session import _add_downsampling, per_session_limit

    conf_file = tmp_path / "robot.json5"
    conf_file.write_text('{ downsampling: [{ id: "mine", flows: ["ingress"], messages: ["put"], '
                         'rules: [{ key_expr: "a/b", freq: 1.0 }] }, { id: "hello", flows: ["ingress"], '
                         'messages: ["query"], rules: [{ key_expr: "rcci/x/hello", freq: 1.0 }] }] }')
    conf = load_config(conf_file)
    _add_downsampling(conf, (per_session_limit("hello", "rcci/x/hello", 5.0),
                             per_session_limit("other", "rcci/x/other", 2.0)))
    got = {e["id"]: e["rules"][0]["freq"] for e in json.loads(conf.get_json("downsampling"))}
    assert got == {"mine": 1.0, "hello": 1.0, "other": 2.0}


def test_the_cell_command_writes_a_ca_identities_and_configurations(tmp_path):
    from cryptography import x509
    from cryptography.x509.oid import NameOID

    written = make_cell(tmp_path, ["lab/puma"], ["10.0.0.1"], 7448, observers=["monitor"])
    assert set(written) == {"robot", "controller", "monitor"}
    ca = x509.load_pem_x509_certificate((tmp_path / "ca.pem").read_bytes())
    for name in written:
        cert = x509.load_pem_x509_certificate((tmp_path / f"{name}.pem").read_bytes())
        assert cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value == name
        cert.verify_directly_issued_by(ca)
        sans = [str(v.value) for v in cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value]
        assert "localhost" in sans and "10.0.0.1" in sans
        assert stat.S_IMODE((tmp_path / f"{name}-key.pem").stat().st_mode) == 0o600
    robot = json.loads(written["robot"].read_text())
    assert robot["listen"]["endpoints"] == ["tls/10.0.0.1:7448"]
    assert robot["transport"]["link"]["tls"]["enable_mtls"] is True
    acl = robot["access_control"]
    assert acl["default_permission"] == "deny" and acl["subjects"][0]["cert_common_names"] == ["controller"]
    assert json.loads(written["monitor"].read_text())["connect"]["endpoints"] == ["tls/10.0.0.1:7448"]
    load_config(written["robot"])                 # Zenoh accepts the files


def test_the_cell_command_writes_the_workcell_bus_access_control(tmp_path, capsys):
    from rci.bus.keys import main

    assert main([str(tmp_path), "--cell", "lab", "--task", "puma", "--shared", "puma_q=puma",
                 "--bus-host", "10.0.0.2"]) == 0
    hub = json.loads((tmp_path / "bus-planning.json5").read_text())
    assert hub["listen"]["endpoints"] == ["tls/10.0.0.2:7448"]
    spoke = json.loads((tmp_path / "bus-puma.json5").read_text())
    assert spoke["connect"]["endpoints"] == ["tls/10.0.0.2:7448"] and "access_control" not in spoke
    acl = hub["access_control"]
    rules = {r["id"]: r for r in acl["rules"]}
    assert acl["default_permission"] == "deny"
    assert "rcci/lab/shared/puma_q" in rules["puma: put"]["key_exprs"]
    assert "rcci/lab/flags/set" in rules["planning: put"]["key_exprs"]
    assert not any("flags/set" in k for r in rules.values() if r["id"].startswith("puma") for k in r["key_exprs"])
    load_config(tmp_path / "bus-planning.json5")
    for argv, said in (([], "--robot KEY"), (["--cell", "lab", "--shared", "x=nobody"], "not the planner nor"),
                       (["--cell", "lab", "--task", "controller"], "a plain name other than")):
        with pytest.raises(SystemExit):
            main([str(tmp_path / "bad"), *argv])
        assert said in capsys.readouterr().err


def test_over_tls_on_loopback_the_controller_is_served_and_an_observer_is_not(tmp_path):
    """The cell's configuration on loopback: the controller's query reaches the robot's
    queryable, an observer's (a certificate of the cell, not the controller's) does not."""
    from rci.bus.session import free_endpoint

    port = int(free_endpoint().rsplit(":", 1)[1])
    keys = make_cell(tmp_path, ["t/arm"], ["127.0.0.1"], port)
    robot = open_session(config=keys["robot"])
    try:
        q = robot.declare_queryable("rcci/t/arm/hello", lambda query: query.reply(query.key_expr, b"here"))
        answers = {}
        for name in ("controller", "observer"):
            s = open_session(config=keys[name])
            deadline, got = time.monotonic() + 5, []
            while not got and time.monotonic() < deadline:
                got = [r.ok.payload.to_bytes() for r in s.get("rcci/t/arm/hello", timeout=0.5) if r.ok is not None]
                if name == "observer" and time.monotonic() > deadline - 4:
                    break                       # a second of asking is enough to be sure of a refusal
            answers[name] = got
            s.close()
        q.undeclare()
    finally:
        robot.close()
    assert answers == {"controller": [b"here"], "observer": []}


def test_on_the_workcell_bus_only_a_keys_writer_writes_it(tmp_path):
    """The workcell's access control (python -m rci.bus.keys --cell), on loopback over mutual
    TLS: the hub (the planning level) and an arm process's task write their own keys; an
    observer of the cell writes none (shared value, start_ev, an arm's flags, a channel, a
    request), nor does a task write another's; an identity of another CA does not join."""
    from rci.bus import Bus
    from rci.bus.session import free_endpoint
    from rci.workcell_data import MultiError

    port = int(free_endpoint().rsplit(":", 1)[1])
    keys = make_cell(tmp_path / "cell", [], ["127.0.0.1"], workcell="c", tasks=["puma"],
                     shared={"puma_q": ["puma"], "plan": ["planning"]}, bus_port=port)
    with ExitStack() as stack:
        hub, puma, obs = (stack.enter_context(Bus("c", tasks=(task,), config=str(keys[f"bus {task}"])))
                          for task in ("planning", "puma", "observer"))
        heard: dict[str, list[bytes]] = {"hub": [], "puma": []}
        for who, bus in (("hub", hub), ("puma", puma)):
            bus.session.declare_subscriber("rcci/c/flags/**", lambda s, w=who: heard[w].append(s.payload.to_bytes()))
        puma.session.declare_queryable("rcci/c/arm/puma/request", lambda q: q.reply(q.key_expr, b"info"))
        to_hub = {sender: (bus.channel(sender, "planning"), hub.channel(sender, "planning"))
                  for sender, bus in (("puma", puma), ("observer", obs))}
        time.sleep(0.5)                           # the declarations reach the hub
        puma.shared["puma_q"] = 1.0               # owners write
        hub.shared["plan"] = 3
        obs.shared["puma_q"] = 99.0               # an observer writes nothing ...
        obs.shared["plan"] = 99
        puma.shared["plan"] = 98                  # ... nor does a task write a value it does not own
        for bus, key in ((obs, "set"), (obs, "puma/7"), (puma, "set"), (puma, "puma/7"), (hub, "set")):
            bus.session.put(f"rcci/c/flags/{key}", f"{key} by {bus.tasks}".encode())
        for sender, (send, _) in to_hub.items():
            send.send({"from": sender})
        time.sleep(1.0)
        assert (hub.shared["puma_q"], hub.shared["plan"]) == (1.0, 3)
        assert sorted(heard["hub"]) == [b"puma/7 by frozenset({'puma'})", b"set by frozenset({'planning'})"]
        assert b"set by frozenset({'observer'})" not in heard["puma"] and b"puma/7 by frozenset({'observer'})" \
            not in heard["puma"] and b"set by frozenset({'planning'})" in heard["puma"]
        assert [recv.receive(0.5) for _, recv in to_hub.values()] == [{"from": "puma"}, None]
        ask = lambda bus: [r.ok.payload.to_bytes() for r in bus.session.get("rcci/c/arm/puma/request", timeout=1.0)
                           if r.ok is not None]   # noqa: E731
        assert ask(hub) == [b"info"] and ask(obs) == []            # only the planning level asks the arm
        late = stack.enter_context(Bus("c", tasks=("observer",), config=str(keys["bus observer"])))
        assert (late.shared.get("puma_q"), late.shared.get("plan")) == (1.0, 3)    # members read the owners' values
        other = make_cell(tmp_path / "other", [], ["127.0.0.1"], workcell="c", tasks=["puma"], bus_port=port)
        with pytest.raises(MultiError, match="cannot open a Zenoh session"):
            Bus("c", tasks=("puma",), config=str(other["bus puma"]))
