"""The dynamics fit's grouping (rcci.calib.grouping): the Microbo's slides' equations left out
(the thesis's reason) and what only they determine not identified; with them in, the vertical
slide's weight folded into its rotor and Coulomb columns; nothing folded on the other arms; the
truth and the feed-forward read through it; the refusal when only friction and rotor columns are
dependent."""
from __future__ import annotations

import numpy as np
import pytest

from rcci.calib.grouping import grouping, random_states
from rcci.calib.identification import column_names, identifiable, regressor_columns
from rcci.calib.regressor import full_column_names, full_regressor_columns
from rcci.models import load_robot

ARMS = ("puma260", "microbo", "puma560", "stanford", "panda")


def _states(robot: str, seed: int):
    m = load_robot(robot)
    return random_states(len(m.lower), np.asarray(m.lower, float), np.asarray(m.upper, float), samples=50, seed=seed)


@pytest.fixture
def slides_fitted(monkeypatch):
    """The Microbo with its slides' equations in the fit (as an arm whose slide torques can be measured)."""
    import rcci.calib.unmeasured as unmeasured

    monkeypatch.setattr(unmeasured, "TORQUE_UNMEASURED", {})
    grouping.cache_clear()
    yield
    grouping.cache_clear()


def test_the_microbo_slides_equations_are_left_out() -> None:
    from rcci.calib.regressor import fitted_joints, left_out

    g = grouping("microbo")
    assert fitted_joints("microbo") == [0, 3, 4, 5] and "impractical" in left_out("microbo")
    assert set(g.eliminated) == {"M2", "IA2", "IA3", "FC2+", "FC2-", "FV2+", "FV2-", "FC3+", "FC3-", "FV3+", "FV3-"}
    assert g.as_section()["not_identified"] == list(g.eliminated) and g.formulas() == []
    assert "M3R" in g.names and identifiable("microbo") is None


def test_the_microbo_slide_weight_is_folded_into_its_rotor_and_coulomb_columns(slides_fitted) -> None:
    g = grouping("microbo")
    grav = float(load_robot("microbo").gravity)
    assert g.eliminated == ("M2",)
    assert g.formulas() == ["IA2R = IA2 + M2 + M3R", f"FC2+R = FC2+ + {grav:.6g} M2 + {grav:.6g} M3R",
                            f"FC2-R = FC2- - {grav:.6g} M2 - {grav:.6g} M3R"]
    assert np.count_nonzero(g.mask == 0) == 2       # M2's and M3R's parts in joint 2's equation moved
    assert "M2" not in column_names("microbo") and {"IA2R", "FC2+R", "FC2-R"} <= set(column_names("microbo"))
    assert identifiable("microbo") is None


@pytest.mark.parametrize("robot", ARMS)
def test_grouped_columns_give_the_full_models_torques(robot: str) -> None:
    """Y_full x = Y (K x) on moving states never used to find the grouping, any parameters x."""
    g = grouping(robot)
    q, qd, qdd = _states(robot, seed=7)
    from rcci.calib.regressor import fitted_joints
    used = fitted_joints(robot)
    x = np.random.default_rng(3).normal(size=len(full_column_names(robot)))
    full = (full_regressor_columns(robot, q, qd, qdd) @ x)[:, used]
    grouped = (regressor_columns(robot, q, qd, qdd) @ (g.K @ x))[:, used]
    assert np.max(np.abs(full - grouped)) <= 1e-9 * max(1.0, np.max(np.abs(full)))
    if robot != "microbo":
        assert g.eliminated == () and np.array_equal(g.K, np.eye(len(g.full)))


def test_feedforward_takes_what_the_fit_did_not_identify_from_the_data_file(tmp_path) -> None:
    """The Microbo's file names its slides' parameters not identified: the model takes the data
    file's for them (masses, rotors, friction of joints 2 and 3) and the fit's for the rest."""
    import rccl.kinematics as kin
    from rcci.calib.params import dumps
    from rcci.models.params import SCHEMA
    from rccl.feedforward import DynamicsModel, data_file_base_parameters

    g = grouping("microbo")
    x = np.random.default_rng(2).uniform(0.1, 1.0, len(g.names))
    path = tmp_path / "p.toml"
    path.write_text(dumps({"calib": {"schema": SCHEMA, "robot": "microbo"},
                           "dynamics": {"names": list(g.names), "values": [float(v) for v in x],
                                        "errors": [0.0] * len(x), **g.as_section()}}))
    km = kin.load("microbo")
    model = DynamicsModel(km, str(path))
    base = dict(zip(km.BASE_PARAMETERS, data_file_base_parameters("microbo")))
    fitted = dict(zip(g.names, x))
    for k, name in enumerate(km.BASE_PARAMETERS):
        assert model.theta[k] == pytest.approx(base[name] if name in g.eliminated else fitted[name], rel=1e-12)
    fr = load_robot("microbo").friction
    assert model.fitted_friction[0][1] == pytest.approx(fr.coulomb_pos.values[1])
    assert model.fitted_friction[0][3] == pytest.approx(fitted["FC4+"])


def test_truth_of_the_microbo_is_grouped(slides_fitted) -> None:
    """simula's truth read through the grouping: IA2 + M2 + M3R, F_c2+- +- g (M2 + M3R); M3R itself."""
    import rccl.kinematics as kin
    from rcci.calib.dynamics_truth import link_inertials, simula_arm, truth_parameters

    params = {"calib": {"schema": 1, "robot": "microbo"}, "inertials": {"mass_scale": [1.0, 1.2, 0.9, 1.0, 1.0, 1.0]}}
    from rcci.models.params import SCHEMA
    params["calib"]["schema"] = SCHEMA
    t = dict(zip(column_names("microbo"), truth_parameters("microbo", params)))
    arm = simula_arm("microbo", params)
    m, com, inertia = link_inertials(arm)
    beta = dict(zip(kin.load("microbo").BASE_PARAMETERS,
                    kin.load("microbo").base_parameters(m, com, inertia, np.diag(arm.rotor))))
    grav = float(load_robot("microbo").gravity)
    w = beta["M2"] + beta["M3R"]
    assert t["IA2R"] == pytest.approx(beta["IA2"] + w, rel=1e-9)
    assert t["FC2+R"] == pytest.approx(arm.truth.coulomb_pos[1] + grav * w, rel=1e-9)
    assert t["FC2-R"] == pytest.approx(arm.truth.coulomb_neg[1] - grav * w, rel=1e-9)
    assert t["M3R"] == pytest.approx(beta["M3R"], rel=1e-12) and t["MX3"] == pytest.approx(beta["MX3"], rel=1e-12)


def test_feedforward_splits_the_grouped_values_with_the_data_files_weight(slides_fitted, tmp_path) -> None:
    """A parameter file with the grouped columns: in motion the model's torques are the grouped
    fit's; the weight M2 is the data file's."""
    import rccl.kinematics as kin
    from rcci.calib.params import dumps
    from rcci.models.params import SCHEMA
    from rccl.feedforward import DynamicsModel, data_file_base_parameters

    robot = "microbo"
    g = grouping(robot)
    rng = np.random.default_rng(5)
    x = rng.uniform(0.1, 1.0, len(g.names))             # any grouped values
    path = tmp_path / "p.toml"
    path.write_text(dumps({"calib": {"schema": SCHEMA, "robot": robot},
                           "dynamics": {"names": list(g.names), "values": [float(v) for v in x],
                                        "errors": [0.0] * len(x), **g.as_section()}}))
    km = kin.load(robot)
    model = DynamicsModel(km, str(path))
    q, qd, qdd = _states(robot, seed=11)
    want = regressor_columns(robot, q, qd, qdd) @ x
    got = np.array([model.torques(a, b, c) + model.friction(b) for a, b, c in zip(q, qd, qdd)])
    assert np.max(np.abs(got - want)) <= 1e-9 * np.max(np.abs(want))
    m2, m3 = km.BASE_PARAMETERS.index("M2"), km.BASE_PARAMETERS.index("M3R")
    assert model.theta[m2] == pytest.approx(data_file_base_parameters(robot)[m2], rel=1e-12)
    assert model.theta[m3] == pytest.approx(x[list(g.names).index("M3R")], rel=1e-12)


def test_dependent_friction_columns_alone_are_refused(monkeypatch, tmp_path, capsys) -> None:
    """No rigid-body parameter to fold: `calib record dynamics` refuses before recording, naming them."""
    import rcci.calib.identification as ident
    from rcci.calib.__main__ import main

    real = ident.regressor_columns

    def twin(robot, q, qd, qdd):          # joint 6's two viscous columns made one
        Y = real(robot, q, qd, qdd).copy()
        Y[:, :, -1] = Y[:, :, -2]
        return Y

    monkeypatch.setattr(ident, "regressor_columns", twin)
    assert main(["record", "dynamics", "--simula", "--seed 3", "--robot", "puma260",
                 "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert "robot puma260: the dynamics fit cannot identify" in err and "FV6+" in err and "FV6-" in err
    assert "friction and rotor columns alone" in err
    assert not list((tmp_path / "a").glob("*.rcilog*")) if (tmp_path / "a").exists() else True


@pytest.mark.parametrize("robot", ("microbo", "puma260"))
def test_the_designs_regressor_is_the_fits(robot: str) -> None:
    """rcci.calib.excitation.design_rows has the fit's columns in the fit's order, grouped and
    masked alike (its tanh stands for the direction: equal where |qd| >> SIGN_SPEED)."""
    from rcci.calib.excitation import SIGN_SPEED, design_rows

    q, qd, qdd = _states(robot, seed=13)
    f = design_rows(robot)
    A = np.stack([np.asarray(f(a, b, c)) for a, b, c in zip(q, qd, qdd)])
    B = regressor_columns(robot, q, qd, qdd)
    assert A.shape == B.shape and np.abs(qd).min() >= 4 * SIGN_SPEED
    assert np.max(np.abs(A - B)) <= 1e-3 * max(1.0, np.max(np.abs(B)))
