"""Issue 30: `calib report` on an arm whose data file states no thesis bounds (the PUMA 560's has no
`uncertainty`, `variation` nor `static_typical_*`): Tables 4.1-4.4 and 4.6 print "-" (or "no bound")
in the thesis's columns and count no thesis check, where they stopped the PUMA 560 campaign's report
with a KeyError; the fit's own checks are still counted."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from rcci.calib.fits import friction, sensitivity, static
from rcci.calib.friction import DirectionFit, FrictionResult
from rcci.calib.outcome import FitOutcome
from rcci.calib.registry import ReportContext
from rcci.calib.robot import robot_info
from rcci.calib.sensitivity import SensitivityResult


def _ctx(checked: list) -> ReportContext:
    info = robot_info("puma560")
    truth = SimpleNamespace(sigma=np.full(6, 0.3), coulomb_pos=np.full(6, 1.0), coulomb_neg=np.full(6, 1.0),
                            viscous_pos=np.full(6, 0.5), viscous_neg=np.full(6, 0.5), variation=np.zeros(6),
                            hold_mean=np.full(6, 0.2), hold_std=np.full(6, 0.05))
    return ReportContext(info, truth, lambda table, ok: checked.append(table) or ("yes" if ok else "**no**"),
                         [], {}, "fitted.toml")


def test_tables_of_an_arm_without_thesis_bounds():
    info = robot_info("puma560")
    assert "uncertainty" not in info.nominal["motors"]["torque_sensitivity"]
    checked: list[str] = []
    ctx = _ctx(checked)
    s = SensitivityResult(2, 6, 0.301, 0.002, 0.005, np.full(6, 0.301))
    text = "\n".join(sensitivity.report(ctx, FitOutcome("sensitivity", "", {}, [s])))
    assert "| 2 | 0.2600 | - | 0.3000 | 0.3010 |" in text
    assert checked == ["4.1 fit"]
    checked.clear()
    fit = lambda c: DirectionFit(coulomb=c, coulomb_err=0.05, viscous=0.5, viscous_err=0.01, points=8)  # noqa: E731
    rows = friction._rows([FrictionResult(3, fit(1.02), fit(0.99), 0.0)], info.nominal["friction"], ctx.truth,
                          ctx.check, "4.2", "coulomb", 1.0, ".3f", lambda f: "")
    assert len(rows) == 2 and all("(no bound)" in r and r.endswith("| - | yes |") for r in rows)
    assert checked == ["4.2 fit", "4.2 fit"]
    res = SimpleNamespace(joint=1, samples=20, maximum=0.4, minimum=-0.3, mean=0.21, std=0.05)
    text = "\n".join(static.report(ctx, FitOutcome("static", "", {}, [res])))
    assert "| 1 | - | 0.400 | - | -0.300 | - | 0.200 | 0.210 | - | 0.050 | 0.050 |" in text
