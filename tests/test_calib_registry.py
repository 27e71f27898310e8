"""The registry of fits (rcci.calib.registry): every module of calib/fits declares one kind, and
the commands take their kinds, order and sections from it."""
from __future__ import annotations

import glob
import os
import subprocess
import sys
from pathlib import Path

import pytest

from rcci.calib import registry
from rcci.calib.exceptions import CalibError
from rcci.calib.logs import LOG_DIR

ROOT = Path(__file__).resolve().parent.parent


def test_every_module_of_calib_fits_is_a_kind_named_after_it():
    modules = sorted(p.stem for p in (ROOT / "calib" / "fits").glob("*.py") if p.stem != "__init__")
    assert sorted(registry.names()) == modules
    for kind in registry.kinds():
        assert callable(kind.fit) and callable(kind.report) and callable(kind.record) and callable(kind.regen)
        assert kind.title and kind.section


def test_the_three_orders_are_each_a_permutation():
    for by in ("order", "record_order", "report_order"):
        places = [getattr(k, by) for k in registry.kinds(by)]
        assert places == sorted(set(places)), (by, places)


def test_the_chained_fit_fits_every_input_before_the_fits_that_need_it():
    """Sensitivities turn currents into torques for every other current-based fit;
    gravity is subtracted by static and breakaway, and enters friction's windows."""
    order = registry.names("order")
    assert order.index("sensitivity") < min(order.index(k) for k in ("gravity", "friction", "static", "breakaway"))
    assert order.index("gravity") < min(order.index(k) for k in ("friction", "static", "breakaway"))
    assert order.index("kinematics") < order.index("gravity")


def test_an_unknown_kind_is_refused_with_the_known_ones():
    with pytest.raises(CalibError, match="unknown fit kind 'torque'; one of sensitivity, "):
        registry.kind("torque")


#: kinds whose logs calib/logs/ does not ship, and why
NOT_SHIPPED = {"dynamics": "validated against a hidden truth with moved inertials (bench.identification, "
                           "reports/identification.md); the shipped logs' truth keeps the URDF's"}


def test_every_shipped_log_names_a_registered_kind():
    from rcci.calib.logs import load_trace

    seen = {load_trace(p).experiment for p in sorted(glob.glob(os.path.join(LOG_DIR, "*.rcilog.*")))}
    assert seen <= set(registry.names())
    assert set(registry.names()) - set(NOT_SHIPPED) <= seen


def test_the_cli_offers_the_registered_kinds_and_their_titles():
    out = subprocess.run([sys.executable, "-m", "rcci.calib", "fit", "--help"], capture_output=True, text=True,
                         cwd=ROOT, timeout=60)
    assert out.returncode == 0
    text = " ".join(out.stdout.split())
    for kind in registry.kinds():
        assert kind.name in text and " ".join(kind.title.split()) in text
    out = subprocess.run([sys.executable, "-m", "rcci.calib", "record", "--help"], capture_output=True, text=True,
                         cwd=ROOT, timeout=60)
    assert "{" + ",".join(registry.names() + ("all",)) + "}" in out.stdout.replace("\n", "").replace(" ", "")


def test_a_fit_writes_only_its_own_section(tmp_path):
    """The sections a fit returns are the one its kind declares."""
    from rcci.calib.fitting import run_fit
    from rcci.calib.logs import load_trace
    from rcci.calib.robot import robot_info

    info = robot_info("puma260")
    paths = sorted(glob.glob(os.path.join(LOG_DIR, "sensitivity-*.rcilog.*")))
    out = run_fit("sensitivity", [load_trace(p) for p in paths], info, None)
    kind = registry.kind("sensitivity")
    assert set(out.sections) == {kind.section}
    assert set(kind.merge_keys) <= set(out.sections[kind.section])
