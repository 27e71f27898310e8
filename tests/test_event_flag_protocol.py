"""One event-flag API: the local, bus and Petri-net-recording forms implement rccl.event_flags.EventFlags."""
from __future__ import annotations

import inspect

import pytest

import rccl.events
from rccl.bus.planning import BusEvents
from rccl.event_flags import PRIMITIVES, EventFlags
from rccl.events import EventError
from rccl.petri import FlagProgram

FORMS = {"local": rccl.events, "bus": BusEvents, "recording": FlagProgram}


def _params(fn) -> list[tuple[str, object, object]]:
    """(name, kind, default) of each parameter but ``self``."""
    return [(p.name, p.kind, p.default) for p in inspect.signature(fn).parameters.values() if p.name != "self"]


@pytest.mark.parametrize("form", FORMS)
def test_each_form_has_every_primitive_with_the_protocols_parameters(form):
    impl = FORMS[form]
    for name in PRIMITIVES:
        assert _params(getattr(impl, name)) == _params(getattr(EventFlags, name)), f"{form}.{name}"
    assert isinstance(impl, EventFlags) if form == "local" else issubclass(impl, EventFlags)


@pytest.mark.parametrize("form", FORMS)
def test_each_form_refuses_a_bad_code_with_the_same_words(form):
    ev = {"local": rccl.events, "bus": BusEvents.__new__(BusEvents), "recording": FlagProgram()}[form]
    # the code is checked before anything else is looked at: the bus form needs no bus for this
    with pytest.raises(EventError, match=r"^start_ev: start codes are positive integers \(rule 4; NULL = 0 is "
                                         r"reserved\), got 0$"):
        ev.start_ev(0)
    for bad in (1, 0, True, 2.5):
        with pytest.raises(EventError, match=r"^stop_ev: stop codes are negative integers"):
            ev.stop_ev(bad)
