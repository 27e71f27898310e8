"""A log in SI units (issue 29, item 1): rci.log_units and its MCAP (Foxglove schemas) and Parquet exports.

The log is recorded here on a lockstep simula: 40 cycles with every motor commanded by
position (joint 1 ramping 3 counts a cycle), then 20 with motors 1-5 by position and motor 6
by current (50 DAC units). On the PUMA 260 the wrist is coupled (G and R are not diagonal), so
the second part has commanded positions for joints 1-5 only and a commanded torque for joint
6 only. The exported files are read back with the mcap reader and pyarrow and every SI value
is compared with the log, T6 with the generated kinematics module (rccl.kinematics.puma260).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from mcap.reader import make_reader

from rccl.kinematics import puma260 as kin
from rci.chg import CUR, POS
from rci.conversions import Conversions
from rci.export import si_columns, to_mcap, to_parquet
from rci.log_units import log_in_si, quaternion
from rci.recorder import Recorder, read_log
from rci.session import Session
from rci.simula.process import SimulaProcess

ROOT = Path(__file__).resolve().parent.parent
CONV = Conversions.for_robot("puma260")
RAMP = 3            # counts a cycle on motor 1
DAC6 = 50


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("si") / "run.rcilog"
    rec = Recorder(path, robot="puma260", rate_hz=100)
    with SimulaProcess("-p", "--power-on", lockstep=True) as sim:
        with Session(sim.url, "puma260", rate_hz=100, signals=False, lock_memory=False, on_error="raise",
                     timeout=2.0) as s:
            start: list[int] = []

            def f1():
                if not start:
                    start.extend(int(x) for x in s.how.pos)
                k = s.timing.count
                for m in range(6):
                    if m == 5 and k >= 40:
                        s.chg.motion[m].issue(CUR, DAC6)
                    else:
                        s.chg.motion[m].issue(POS, start[m] + (RAMP * min(k, 40) if m == 0 else 0))
            s.record(rec)
            s.control(f1)
            assert s.wait(until=lambda: s.timing.count >= 60, seconds=20)
            s.release()
    rec.close()
    return path


def test_the_log_in_si_units(recorded):
    log = read_log(recorded)
    si = log_in_si(log)
    r = log.records
    assert np.allclose(si.q, CONV.counts_to_angles(r["how_pos"].astype(float)), rtol=0, atol=1e-15)
    pos = np.all(r["chg_motion_com"] == POS, axis=1)
    assert pos.sum() >= 30 and (~pos).sum() >= 10
    # every motor by position: every joint has its commanded value; T6 there is fk of it
    assert np.allclose(si.q_cmd[pos], CONV.counts_to_angles(r["chg_motion_value"][pos].astype(float)), atol=1e-15)
    assert np.allclose(si.T6_cmd[pos], kin.fk(si.q_cmd[pos]), atol=1e-12)
    # motor 6 by current: joint 6's position depends on motors 4-6 (R), so it has none; its torque
    # depends on motor 6 only (G^T), joints 1-5 have no commanded torque
    cur = ~pos
    assert np.all(np.isfinite(si.q_cmd[cur][:, :5])) and np.all(np.isnan(si.q_cmd[cur][:, 5]))
    assert np.all(np.isnan(si.T6_cmd[cur]))
    tau6 = CONV.G[5, 5] * DAC6 / CONV.k_dac[5]
    assert np.allclose(si.tau_cmd[cur][:, 5], tau6) and np.all(np.isnan(si.tau_cmd[cur][:, :5]))
    assert np.all(np.isnan(si.tau_cmd[pos]))
    # the ramp's rate: 3 counts a cycle at 100 Hz on joint 1 (R diagonal there), robot clock
    ramp = pos & (r["chg_motion_value"][:, 0] - r["chg_motion_value"][0, 0] < RAMP * 39)
    ramp[0] = False
    assert np.allclose(si.qd_cmd[ramp][:, 0], RAMP * 100 / CONV.R[0, 0], rtol=1e-6)
    assert np.allclose(np.diff(si.t), 0.01, rtol=1e-6)
    assert np.allclose(si.tau, CONV.adc_to_joint_torques(r["how_adcr"][:, :6].astype(float)))
    assert np.allclose(si.current, CONV.adc_to_currents(r["how_adcr"][:, :6].astype(float)))
    # measured T6 and every link: the DH chain equals the generated kinematics module
    assert np.allclose(si.T6, kin.fk(si.q), atol=1e-12)
    assert si.unit("q") == ["rad"] * 6 and si.unit("tau_cmd") == ["N m"] * 6


def _messages(path: Path) -> tuple[dict, dict]:
    schemas, messages = {}, {}
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            schemas[channel.topic] = (schema.name, schema.encoding, json.loads(schema.data), channel.message_encoding)
            messages.setdefault(channel.topic, []).append((message.log_time, json.loads(message.data)))
    return schemas, messages


def _pose(msg: dict) -> np.ndarray:
    x, y, z, w = (msg["rotation"][k] for k in "xyzw")
    T = np.eye(4)
    T[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    T[:3, 3] = [msg["translation"][k] for k in "xyz"]
    return T


def test_mcap_has_foxglove_channels_with_the_si_values(recorded, tmp_path):
    log = read_log(recorded)
    si = log_in_si(log)
    out = tmp_path / "run.mcap"
    to_mcap(log, out)
    schemas, messages = _messages(out)
    expect = {"/joints/measured": "foxglove.JointStates", "/joints/commanded": "foxglove.JointStates",
              "/tf": "foxglove.FrameTransforms", "/T6": "foxglove.FrameTransform",
              "/T6/commanded": "foxglove.FrameTransform", "/motor_currents": "rci.motor_currents"}
    for topic, name in expect.items():
        sname, encoding, schema, msg_encoding = schemas[topic]
        assert (sname, encoding, msg_encoding) == (name, "jsonschema", "json"), topic
        assert schema["title"] == name
    assert set(schemas["/T6"][2]["properties"]) == {"timestamp", "parent_frame_id", "child_frame_id",
                                                    "translation", "rotation"}
    n = len(log)
    t_ns = np.round(log.records["t"] * 1e9).astype(np.int64)
    measured = messages["/joints/measured"]
    assert len(measured) == n and [m[0] for m in measured] == t_ns.tolist()
    for i, (_, msg) in enumerate(measured):
        assert [j["name"] for j in msg["joints"]] == [f"joint{k}" for k in range(1, 7)]
        for key, col in (("position", si.q), ("velocity", si.qd), ("effort", si.tau)):
            assert np.array_equal([j[key] for j in msg["joints"]], col[i]), (i, key)
        assert msg["timestamp"]["sec"] * 10**9 + msg["timestamp"]["nsec"] == t_ns[i]
    # commanded: fields present exactly where the log has a value
    for i, (_, msg) in enumerate(messages["/joints/commanded"]):
        got = {j["name"]: j for j in msg["joints"]}
        for k in range(6):
            entry = got.get(f"joint{k + 1}", {})
            assert ("position" in entry) == bool(np.isfinite(si.q_cmd[i, k]))
            assert ("effort" in entry) == bool(np.isfinite(si.tau_cmd[i, k]))
            if "position" in entry:
                assert entry["position"] == si.q_cmd[i, k]
            if "effort" in entry:
                assert entry["effort"] == si.tau_cmd[i, k]
    # T6 and the /tf chain: both give the generated module's fk
    fk = kin.fk(si.q)
    for i, (_, msg) in enumerate(messages["/T6"]):
        assert msg["parent_frame_id"] == "base_link" and msg["child_frame_id"] == "T6"
        assert np.allclose(_pose(msg), fk[i], atol=1e-12)
    for i, (_, msg) in enumerate(messages["/tf"]):
        chain = msg["transforms"]
        assert [(c["parent_frame_id"], c["child_frame_id"]) for c in chain] == \
            [("base_link", "link1")] + [(f"link{k}", f"link{k + 1}") for k in range(1, 6)]
        T = np.eye(4)
        for c in chain:
            T = T @ _pose(c)
        assert np.allclose(T, fk[i], atol=1e-12)
    commanded = messages["/T6/commanded"]
    complete = np.all(np.isfinite(si.q_cmd), axis=1)
    assert len(commanded) == complete.sum() > 0
    for (t, msg), q in zip(commanded, si.q_cmd[complete]):
        assert msg["child_frame_id"] == "T6_commanded" and np.allclose(_pose(msg), kin.fk(q), atol=1e-12)
    currents = messages["/motor_currents"]
    assert np.array_equal([m["value"] for _, m in currents], si.current)


def test_parquet_has_the_si_columns_with_units(recorded, tmp_path):
    log = read_log(recorded)
    si = log_in_si(log)
    out = tmp_path / "run.parquet"
    to_parquet(log, out)
    table = pq.read_table(out)
    units = {f.name: (f.metadata or {}).get(b"unit", b"").decode() for f in table.schema}
    for j in range(1, 7):
        assert np.array_equal(table.column(f"q_{j}").to_numpy(), si.q[:, j - 1]) and units[f"q_{j}"] == "rad"
        assert units[f"qd_{j}"] == "rad/s" and units[f"tau_cmd_{j}"] == "N m" and units[f"current_{j}"] == "A"
        assert np.array_equal(table.column(f"tau_cmd_{j}").to_numpy(), si.tau_cmd[:, j - 1], equal_nan=True)
    T6 = np.stack([table.column(f"T6_{a}").to_numpy() for a in "xyz"], axis=1)
    assert np.allclose(T6, kin.fk(si.q)[:, :3, 3], atol=1e-12) and units["T6_x"] == "m"
    quat = np.stack([table.column(f"T6_q{a}").to_numpy() for a in "xyzw"], axis=1)
    assert np.allclose(quat, quaternion(kin.fk(si.q)[:, :3, :3]), atol=1e-12)
    assert set(si_columns(si)) <= set(table.column_names)


def test_a_prismatic_arm_is_in_metres(tmp_path):
    """The Microbo's joints 2 and 3 slide: their columns are m, m/s, N (a log made here, no robot needed)."""
    from rci.how import How

    conv = Conversions.for_robot("microbo")
    path = tmp_path / "m.rcilog"
    q = np.array([0.1, 0.05, 0.02, 0.3, 2.0, 0.1])
    with Recorder(path, robot="microbo") as rec:
        h = How()
        for k in range(5):
            h.cycle, h.time_ns = k, k * 10**7
            h.pos[:] = conv.angles_to_counts_int(q + 0.001 * k)
            rec.append(h, None)
    si = log_in_si(read_log(path))
    assert si.unit("q") == ["rad", "m", "m", "rad", "rad", "rad"] and si.unit("tau")[1] == "N"
    assert np.allclose(si.qd, 0.1, atol=conv.rounding_step().max() * 100)
    from rccl.kinematics import microbo
    assert np.allclose(si.T6, microbo.fk(si.q), atol=1e-12)


def test_the_replay_shows_the_record_in_si_units(recorded):
    from rcci.view.replay import Replay

    replay = Replay(recorded)
    si = log_in_si(read_log(recorded))
    i = 45                                              # motor 6 by current: a torque command on joint 6
    rows = replay.table(i).splitlines()
    joint6 = [c.strip() for c in rows[2 + 5].split("|")[1:-1]]
    assert joint6[0] == "6" and joint6[1] == f"{si.q[i, 5]:+.4f}" and joint6[2] == f"{si.qd[i, 5]:+.4f}"
    assert joint6[5] == f"{si.tau_cmd[i, 5]:+.4f}" and joint6[4] == ""      # no position command there
    assert joint6[6] == "rad, rad/s, N m"
    assert f"T6 at ({si.T6[i, 0, 3]:+.4f}" in rows[-1]
    assert np.array_equal(replay.q, si.q) and np.isnan(replay.q_cmd[i]).all()
