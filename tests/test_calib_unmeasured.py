"""The Microbo's slides: no current-based measurement plans them (rcci.calib.unmeasured: the
thesis's reason, named in the campaign's notes), and asked for by --joints they are refused;
the fits that need the gravity coefficients it cannot measure are refused before recording."""
from __future__ import annotations

from rcci.calib.unmeasured import unmeasured_joints, why_unmeasured


def test_a_microbo_campaign_plans_no_torque_measurement_of_its_slides(tmp_path) -> None:
    from rcci.calib import registry
    from rcci.calib.regen import campaign_plans
    from rcci.calib.registry import RegenContext
    from rcci.calib.robot import robot_info

    assert unmeasured_joints("microbo") == (2, 3) and why_unmeasured("puma260") is None
    ctx = RegenContext(str(tmp_path), str(tmp_path / ".work"), 1, None, robot_info("microbo"))
    kinds = tuple(k.name for k in registry.kinds("record_order") if k.name != "dynamics")
    plans, refused = campaign_plans(ctx, kinds, skip_refused=True)
    names = {getattr(p, "name", None) for _, p in plans} | {n for _, p in plans for n in getattr(p, "logs", ())}
    for j in (2, 3):
        assert not any(n and (n.endswith(f"-j{j}") or f"-j{j}-" in n) for n in names), names
    for kind in ("friction", "sensitivity"):
        assert any(n.startswith(f"{kind}: not recorded") and "impractical" in n for n in ctx.notes), kind
    assert "friction-j1" in names and "friction-j4" in names
    # the breakaway and static fits take gravity off with the fitted coefficients, which the
    # Microbo's revolute sweeps cannot identify (c12): refused before anything is recorded
    for kind in ("breakaway", "static"):
        assert "subtracts gravity" in refused[kind] and "c12" in refused[kind], refused


def test_asking_for_a_slide_is_refused_with_the_reason(tmp_path, capsys) -> None:
    from rcci.calib.__main__ import main

    assert main(["record", "friction", "--robot", "microbo", "--simula", "--seed 3", "--joints", "2",
                 "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert "joint 2" in err and "impractical" in err
