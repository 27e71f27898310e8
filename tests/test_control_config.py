"""The control configuration (rci.control_config), the rate's one validation and its typed change
(rci.rate), and the lifecycle shared by a session and a workcell (rci.lifecycle): unit tests,
no robot needed."""
from __future__ import annotations

import dataclasses
import math

import pytest

from rci.chg import Chg
from rci.control_config import ControlConfig
from rci.lifecycle import Lifecycle
from rci.multi import Workcell
from rci.rate import RateChange, check_rate_hz, rate_from_code
from rci.realtime import RealtimeSettings
from rci.session import Session


def test_defaults_and_what_they_mean():
    c = ControlConfig()
    assert (c.rate_hz, c.period, c.late_policy) == (36, 1 / 36, "error")
    assert c.timeout_for(1 / 36) == pytest.approx(2 / 36)
    assert c.timeout_for(1 / 1000) == 0.02                       # min_timeout
    lock = c.changed(lockstep=True)
    assert lock.late_policy == "count" and lock.timeout_for(1 / 1000) == 0.25
    assert [c.late_limit_for(r) for r in (36, 250, 1000)] == [3, 5, 20]
    assert c.user_hang_limit(0.01) == 0.02 and lock.user_hang_limit(0.01) == 2.0


@pytest.mark.parametrize("option, value, words", [
    ("rate_hz", 2000, "rate_hz must be 4..1000 Hz"),
    ("rate_hz", 36.5, "rate_hz must be a whole number"),
    ("rate_hz", "36", "rate_hz must be a whole number"),
    ("rate_hz", True, "rate_hz"),
    ("timeout", -1.0, "timeout must be a number of seconds > 0"),
    ("start_timeout", math.inf, "start_timeout"),
    ("overrun", "never", "overrun must be"),
    ("late_limit", 0, "late_limit must be"),
    ("max_commands", 0, "max_commands must be"),
    ("limits", "table", "limits must be"),
    ("priority", 0, "priority must be an integer 1..99"),
    ("gc", "sometimes", "gc must be one of"),
    ("switch_interval", 2.0, "switch_interval must be"),
])
def test_a_bad_setting_is_refused_once_with_its_name(option, value, words):
    with pytest.raises(ValueError, match=words):
        ControlConfig.build(**{option: value})
    with pytest.raises(ValueError, match=words):          # the session's one validation is the same
        Session("socket://127.0.0.1:1", **{option: value})


def test_the_record_is_immutable_and_changes_make_a_new_one():
    c = ControlConfig.build(rate_hz=100, gc="off")
    with pytest.raises(dataclasses.FrozenInstanceError):
        c.rate_hz = 250
    d = c.changed(rate_hz=250, gc="leave", timeout=0.5)
    assert (c.rate_hz, c.realtime.gc, c.timeout) == (100, "off", None)
    assert (d.rate_hz, d.realtime.gc, d.timeout) == (250, "leave", 0.5)
    assert isinstance(d.realtime, RealtimeSettings)
    with pytest.raises(ValueError, match="rate_hz"):
        c.changed(rate_hz=3)
    with pytest.raises(TypeError, match="unknown control settings"):
        c.changed(rate=250)


def test_session_keeps_its_settings_in_one_record():
    s = Session("socket://127.0.0.1:1", rate_hz=72.0, timeout=0.1, realtime=False, signals=False)
    assert s.config.rate_hz == 72 and s.rate_hz == 72 and s.period == pytest.approx(1 / 72)
    assert s.config.realtime.link_priority == 0 and s.timeout_for(1 / 72) == 0.1
    s.configure(rate_hz=250, gc="leave")
    assert s.rate_hz == 250 and s.config.realtime.gc == "leave"
    with pytest.raises(ValueError, match="rate_hz"):
        s.configure(rate_hz=0)


def test_rate_validation_and_the_typed_change():
    assert [rate_from_code(v) for v in (0, 1, 2, 3, 4, 1000)] == [72, 36, 18, 9, 4, 1000]
    with pytest.raises(ValueError, match="neither a code 0..3 nor a rate 4..1000 Hz"):
        rate_from_code(1001)
    assert check_rate_hz(36.0) == 36
    with pytest.raises(ValueError, match="--rate must be 4..1000"):
        check_rate_hz(1, "--rate")          # a thesis code is for chg.rate only, not a rate in Hz
    chg = Chg()
    assert chg.rate_change() is None
    chg.rate.issue(1, 0)
    assert chg.rate_change() == RateChange(72)
    chg.rate.issue(1, 250)
    assert chg.rate_change().hz == 250 and chg.rate_change().period == pytest.approx(0.004)
    for bad in (5000, float("nan"), "250"):
        chg.rate.issue(1, bad)
        with pytest.raises(ValueError, match="chg.rate value"):
            chg.rate_change()


def test_a_session_and_a_workcell_share_one_lifecycle():
    s = Session("socket://127.0.0.1:1", signals=False)
    cell = Workcell({"a": ("socket://127.0.0.1:1", "puma260"), "b": ("socket://127.0.0.1:2", "microbo")})
    assert type(s.lifecycle) is Lifecycle and type(cell.lifecycle) is Lifecycle
    # the arms' own lifecycles give the signals to the workcell's, and the workcell's
    # real-time settings are process-wide, once for all arms
    assert not any(a.lifecycle.use_signals for a in cell.sessions.values())
    assert all(a.config.realtime.gc == "leave" for a in cell.sessions.values())
    given = Session("socket://127.0.0.1:3")
    Workcell({"c": given})
    assert not given.lifecycle.use_signals and given.config.realtime.switch_interval is None
