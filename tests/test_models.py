"""Robot data files and their loader (rci.robot_model): API, thesis values, malformed files."""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from rcci.models import ModelError
from rcci.models import Joint, RobotModel, Source, load_robot, models_dir

MODELS = Path(__file__).resolve().parents[1] / "models"
ROBOTS = ("puma260", "microbo")


# ----------------------------------------------------------------------------- loading

#: joint counts of the arms whose loading the API test checks (the Panda is redundant)
N_JOINTS = {"puma260": 6, "microbo": 6, "puma560": 6, "stanford": 6, "panda": 7}


@pytest.mark.parametrize("name", sorted(N_JOINTS))
def test_loads_with_documented_api(name: str) -> None:
    model = load_robot(name)
    n = N_JOINTS[name]
    assert isinstance(model, RobotModel)
    assert model.name == name and model.n_joints == n and len(model.joints) == n
    assert model.urdf_path.is_file() and model.path == MODELS / f"{name}.toml"
    for i, joint in enumerate(model.joints):
        assert isinstance(joint, Joint) and joint.index == i + 1 and joint.name == f"joint{i + 1}"
        assert joint.kind in ("revolute", "prismatic")
        assert joint.variable == ("theta" if joint.kind == "revolute" else "d")
    for arr in (model.lower, model.upper, model.max_velocity, model.max_current):
        assert arr.shape == (n,) and arr.dtype == float
        with pytest.raises(ValueError):
            arr[0] = 0.0  # read-only
    assert np.all(model.lower < model.upper)
    assert {"ready", "nest"} <= set(model.poses)
    for q in model.poses.values():
        assert q.shape == (n,) and model.within_limits(q)
    assert len(model.links) == n and all(li.mass > 0 for li in model.links)
    assert model.friction.coulomb_pos.values.shape == (n,)
    assert model.conversion.gear_ratio.values.shape == (n, n)
    assert model.base_to_link(model.poses["ready"]).shape == (n, 4, 4)
    assert model.data_frames.shape == (n, 4, 4)
    assert model.gravity == pytest.approx(9.81)


def test_puma_dh_table_in_si() -> None:
    puma = load_robot("puma260")
    assert puma.kinds == ("revolute",) * 6
    assert [round(math.degrees(j.alpha)) for j in puma.joints] == [90, 0, -90, 90, -90, 0]
    assert puma.joints[1].a == pytest.approx(0.2032)
    assert puma.joints[2].d == pytest.approx(0.12624)
    assert puma.joints[3].d == pytest.approx(0.2032)
    assert sum(abs(j.a) for j in puma.joints) == pytest.approx(0.2032)
    assert puma.source("joints.3.d").tag == "thesis Table 3.1"
    assert puma.sources["joints.2.a"].tag == "thesis Table 3.1"
    assert puma.poses["j3A"] == pytest.approx(np.radians([270, 90, -90, 90, 0, 45]))


def test_microbo_dh_table_in_si() -> None:
    mic = load_robot("microbo")
    assert mic.kinds == ("revolute", "prismatic", "prismatic", "revolute", "revolute", "revolute")
    assert [round(math.degrees(j.alpha)) for j in mic.joints] == [0, 90, 0, 90, 90, 0]
    assert mic.joints[1].theta == pytest.approx(math.pi / 2)
    assert all(j.a == 0 for j in mic.joints)
    assert mic.lower[2] > 0  # d3 cannot be negative (thesis 3.4)
    assert mic.lower[4] < math.pi < mic.upper[4] and mic.lower[4] > 0  # contains 180, not 0
    assert mic.friction.coulomb_pos.units[1] == "N" and mic.friction.coulomb_pos.units[0] == "N*m"
    assert mic.conversion.gear_ratio.units[1] == "rad/m"


def test_puma_chapter4_and_appendix_d_values() -> None:
    puma = load_robot("puma260")
    c = puma.gravity_coeffs
    assert (c["c12"].value, c["c13"].value, c["c15"].value) == (5.509, -1.762, -1.192)
    assert (c["c12"].uncertainty, c["c13"].uncertainty, c["c15"].uncertainty) == (0.15, 0.04, 0.005)
    assert puma.source("gravity_coeffs.c13").tag == "thesis Table 4.9"
    f = puma.friction
    assert f.coulomb_pos.values[0] == 0.760 and f.coulomb_neg.values[0] == 0.640
    assert f.viscous_pos.values[0] == pytest.approx(12.03e-3)  # Table 4.3 prints x 1000
    assert f.static_pos.values[1] == 2.23 and f.static_neg.values[1] == 2.04
    assert f.static_typical_std.values[1] == 0.375
    assert puma.motors.torque_sensitivity.values == pytest.approx([0.0732, 0.0751, 0.0786, 0.0358, 0.0349, 0.0305])
    G = puma.conversion.gear_ratio.values
    assert np.allclose(np.triu(G, 1), 0)  # lower triangular: coupled wrist
    assert (G[4, 3], G[5, 3], G[5, 4]) == (-9.8462, 1.0, -6.9424)
    # R = diag(counts per motor rad) G holds for every printed entry but r65 (see README).
    R = puma.conversion.encoder_ratio.values
    Rc = puma.conversion.encoder_ratio_consistent.values
    per_motor_rad = np.diag(Rc) / np.diag(G)
    assert np.allclose(np.abs(per_motor_rad) * 2 * np.pi, puma.conversion.encoder_counts_per_motor_rev.values, rtol=1e-4)
    assert np.allclose(Rc, per_motor_rad[:, None] * G, rtol=2e-4, atol=0.05)
    assert np.argwhere(~np.isclose(R, Rc)).tolist() == [[5, 4]]
    assert puma.conversion.adc_volts_per_count.value == 0.00111
    assert puma.conversion.kappa.values == pytest.approx([1.333] * 6)


def test_puma_ranges_contain_the_table_4_7_sweeps() -> None:
    """Each Table 4.8 measurement moved one joint from its Table 4.7 value - 90 deg to + 90 deg;
    the estimated ranges were chosen to contain those sweeps."""
    puma = load_robot("puma260")
    for pose, joint in (("j5", 5), ("j4", 4), ("j3A", 3), ("j3B", 3), ("j2", 2)):
        for delta in (-math.pi / 2, 0.0, math.pi / 2):
            q = puma.poses[pose].copy()
            q[joint - 1] += delta
            assert puma.within_limits(q), (pose, joint, delta)


@pytest.mark.parametrize("name", ROBOTS)
def test_every_value_has_a_source(name: str) -> None:
    model = load_robot(name)
    assert len(model.sources) > 60
    for field, src in model.sources.items():
        assert isinstance(src, Source)
        assert src.tag.startswith("thesis ") or (src.tag == "estimate" and src.why), field
    assert str(model.source("friction.coulomb_pos.3")) == str(model.source("friction.coulomb_pos"))
    with pytest.raises(KeyError):
        model.source("joints.9.d")


def test_microbo_is_all_estimates_except_dh() -> None:
    mic = load_robot("microbo")
    thesis = {f for f, s in mic.sources.items() if not s.is_estimate}
    assert thesis and all(f.startswith("joints.") and f.rsplit(".", 1)[1] in ("a", "alpha", "d", "theta")
                          for f in thesis)


def _printed_fk_puma(q: np.ndarray, a2: float, d3: float, d4: float) -> np.ndarray:
    """Thesis eq. 3.17 as printed (S23 = sin(theta2 + theta3)), rows n, o, a, p."""
    C1, S1, C2, S2 = math.cos(q[0]), math.sin(q[0]), math.cos(q[1]), math.sin(q[1])
    C23, S23 = math.cos(q[1] + q[2]), math.sin(q[1] + q[2])
    C4, S4, C5, S5, C6, S6 = (f(x) for x in q[3:] for f in (math.cos, math.sin))
    u = -C23 * S4 * S6 - C6 * S23 * S5 + C23 * C4 * C5 * C6
    v = -C4 * S6 - C5 * C6 * S4
    w = (S23 * S5 - C23 * C4 * C5) * S6 - C23 * C6 * S4
    x = C5 * S4 * S6 - C4 * C6
    y = C23 * C4 * S5 + C5 * S23
    r = a2 * C2 - d4 * S23
    return np.array([
        [C1 * u + S1 * v, C1 * w + S1 * x, -C1 * y + S1 * S4 * S5, C1 * r + d3 * S1],
        [S1 * u - C1 * v, S1 * w - C1 * x, -S1 * y - C1 * S4 * S5, S1 * r - C1 * d3],
        [-S23 * S4 * S6 + C23 * C6 * S5 + C4 * C5 * C6 * S23, -(C23 * S5 + C4 * C5 * S23) * S6 - C6 * S23 * S4,
         C23 * C5 - C4 * S23 * S5, a2 * S2 + C23 * d4],
    ])


def _printed_fk_microbo(q: np.ndarray, ny_as_printed: bool = False) -> np.ndarray:
    """Thesis eq. 3.18 as printed, except n_y: the print has ``- C6 S1 S5`` where the A
    matrices 3.10-3.15 (and n = o x a) give ``+ C6 S1 S5`` (see models/README.md)."""
    C1, S1 = math.cos(q[0]), math.sin(q[0])
    d2, d3 = q[1], q[2]
    C4, S4, C5, S5, C6, S6 = (f(x) for x in q[3:] for f in (math.cos, math.sin))
    return np.array([
        [C1 * C6 * S5 - S1 * (S4 * S6 + C4 * C5 * C6), -S1 * (C6 * S4 - C4 * C5 * S6) - C1 * S5 * S6,
         -C4 * S1 * S5 - C1 * C5, C1 * d3],
        [C1 * (S4 * S6 + C4 * C5 * C6) + (-1 if ny_as_printed else 1) * C6 * S1 * S5,
         C1 * (C6 * S4 - C4 * C5 * S6) - S1 * S5 * S6,
         C1 * C4 * S5 - C5 * S1, d3 * S1],
        [C5 * C6 * S4 - C4 * S6, -C5 * S4 * S6 - C4 * C6, S4 * S5, d2],
    ])


@pytest.mark.parametrize("name", ROBOTS)
def test_dh_product_matches_printed_forward_kinematics(name: str) -> None:
    """The data file's DH table (with the derived alpha signs) reproduces eqs. 3.17 / 3.18."""
    model = load_robot(name)
    rng = np.random.default_rng(317)
    for _ in range(200):
        q = rng.uniform(model.lower, model.upper)
        T6 = model.base_to_link(q)[-1]
        if name == "puma260":
            want = _printed_fk_puma(q, model.joints[1].a, model.joints[2].d, model.joints[3].d)
        else:
            want = _printed_fk_microbo(q)
        assert np.max(np.abs(T6[:3, :] - want)) < 1e-12


def test_printed_microbo_ny_is_an_erratum() -> None:
    """Eq. 3.18's printed n_y breaks n = o x a; the corrected sign restores it."""
    q = np.array([0.3, 0.2, 0.3, 0.4, 1.9, 0.6])
    for printed, ok in ((True, False), (False, True)):
        T = _printed_fk_microbo(q, ny_as_printed=printed)
        assert np.allclose(T[:, 0], np.cross(T[:, 1], T[:, 2]), atol=1e-12) is ok


def test_models_dir_env_override(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    root = _copy_models(tmp_path)
    monkeypatch.setenv("RCCI_MODELS", str(root))
    assert models_dir() == root
    assert load_robot("microbo").path == root / "microbo.toml"
    with pytest.raises(ModelError, match="no such robot data file"):
        load_robot("stanford_arm")


def test_reloads_after_edit(tmp_path: Path) -> None:
    root = _copy_models(tmp_path)
    path = root / "puma260.toml"
    assert load_robot(path).gravity == pytest.approx(9.81)
    _edit(path, "gravity = { value = 9.81,", "gravity = { value = 9.80665,")
    assert load_robot(path).gravity == pytest.approx(9.80665)


# ----------------------------------------------------------------------------- malformed files

def _copy_models(tmp_path: Path) -> Path:
    root = tmp_path / "models"
    shutil.copytree(MODELS, root, ignore=shutil.ignore_patterns("README.md"))
    return root


def _edit(path: Path, old: str, new: str, count: int = 1) -> None:
    text = path.read_text()
    assert text.count(old) >= count, f"test setup: {old!r} not in {path.name}"
    path.write_text(text.replace(old, new, count))


J3_D = 'd = { value = 126.24, unit = "mm", uncertainty = 0.50, source = "thesis Table 3.1", why = "shoulder offset between the upper arm and forearm planes" }'
J1_ALPHA = 'alpha = { value = 90.0, unit = "deg", source = "thesis eq. 3.4"'
J5_LOWER = 'lower = { value = -100.0, unit = "deg"'
LIMIT_J2_URDF = '<limit lower="-0.7853981633974483" upper="3.9269908169872414" velocity="2.99"'

# (robot, file to edit, old text, new text, field named in the error, words of the problem)
BROKEN = {
    "missing field": ("puma260", "puma260.toml", J3_D, "", "joints.3.d", "missing field"),
    "missing unit": ("puma260", "puma260.toml", J1_ALPHA, 'alpha = { value = 90.0, source = "thesis eq. 3.4"',
                     "joints.1.alpha", "missing unit"),
    "wrong unit": ("puma260", "puma260.toml", J1_ALPHA, J1_ALPHA.replace('"deg"', '"mm"'),
                   "joints.1.alpha", "wrong unit 'mm'"),
    "unknown unit": ("puma260", "puma260.toml", J1_ALPHA, J1_ALPHA.replace('"deg"', '"grad"'),
                     "joints.1.alpha", "unknown unit 'grad'"),
    "revolute range in metres": ("puma260", "puma260.toml", J5_LOWER, 'lower = { value = -0.1, unit = "m"',
                                 "joints.5.lower", "wrong unit 'm'"),
    "prismatic pose in degrees": ("microbo", "microbo.toml", 'units = ["deg", "m", "m", "deg", "deg", "deg"]',
                                  'units = ["deg", "deg", "m", "deg", "deg", "deg"]', "poses.ready[1]", "wrong unit 'deg'"),
    "lower above upper": ("puma260", "puma260.toml", J5_LOWER, 'lower = { value = 120.0, unit = "deg"',
                          "joints.5.lower", "not below upper"),
    "NaN": ("puma260", "puma260.toml", "values = [0.760, 1.620,", "values = [nan, 1.620,",
            "friction.coulomb_pos[0]", "NaN"),
    "infinite": ("puma260", "puma260.toml", "value = 5.509", "value = inf", "gravity_coeffs.c12", "infinite"),
    "unknown joint kind": ("microbo", "microbo.toml", 'kind = "prismatic"', 'kind = "telescopic"',
                           "joints.2.kind", "unknown joint kind 'telescopic'"),
    "value without source": ("puma260", "puma260.toml", '[gravity_coeffs.c13]\nvalue = -1.762\nunit = "N*m"\nuncertainty = 0.04\nsource = "thesis Table 4.9"',
                             '[gravity_coeffs.c13]\nvalue = -1.762\nunit = "N*m"\nuncertainty = 0.04',
                             "gravity_coeffs.c13", "without a source"),
    "estimate without why": ("puma260", "puma260.toml", 'source = "estimate"\nwhy = "folded rest pose',
                             'source = "estimate"\nnote = "folded rest pose', "poses.nest", "unknown key"),
    "estimate with empty why": ("microbo", "microbo.toml", 'why = "mid-bar, 25 cm behind the wrist centre along z3"',
                                'why = " "', "links.3.com", "estimate without 'why'"),
    "source neither thesis nor estimate": ("puma260", "puma260.toml", 'source = "thesis Table 4.1"\nwhy = "mean',
                                           'source = "Unimation catalogue"\nwhy = "mean',
                                           "motors.torque_sensitivity", "neither"),
    "misspelt key": ("puma260", "puma260.toml", 'a = { value = 0.0, unit = "mm", source = "thesis Table 3.1" }',
                     'a = { value = 0.0, unit = "mm", soruce = "thesis Table 3.1" }', "joints.1.a", "unknown key"),
    "wrong number of joints": ("puma260", "puma260.toml", "n_joints = 6", "n_joints = 5", "joints",
                               "wrong number of joints"),
    "short vector": ("puma260", "puma260.toml", "values = [0.10, 0.20, 0.13, 0.27, 0.10, 0.05]",
                     "values = [0.10, 0.20, 0.13, 0.27, 0.10]", "friction.variation", "has 5 values, expected 6"),
    "pose outside range": ("puma260", "puma260.toml", "values = [0.0, 90.0, -180.0, 0.0, -90.0, 0.0]",
                           "values = [0.0, 90.0, -180.0, 0.0, -190.0, 0.0]", "poses.ready", "outside"),
    "negative friction": ("microbo", "microbo.toml", "values = [1.0, 30.0, 25.0, 0.15, 0.15, 0.10]",
                          "values = [1.0, -30.0, 25.0, 0.15, 0.15, 0.10]", "friction.coulomb_pos", ">= 0"),
    "unphysical inertia": ("puma260", "puma260.toml", "values = [0.0015, 0.0090, 0.0090,",
                           "values = [0.0015, 0.0090, 0.0300,", "links.2.inertia", "not a physical inertia"),
    "invalid TOML": ("puma260", "puma260.toml", "[robot]", "[robot", "<file>", "not valid TOML"),
    "missing URDF": ("puma260", "puma260.toml", 'urdf = "urdf/puma260.urdf"', 'urdf = "urdf/puma261.urdf"',
                     "robot.urdf", "does not exist"),
    "URDF limit disagrees": ("puma260", "urdf/puma260.urdf", LIMIT_J2_URDF,
                             LIMIT_J2_URDF.replace("-0.7853981633974483", "-0.80"), "joint joint2.limit.lower",
                             "disagrees with the data file"),
    "URDF velocity disagrees": ("microbo", "urdf/microbo.urdf", 'upper="0.35" velocity="0.2"',
                                'upper="0.35" velocity="0.3"', "joint joint2.limit.velocity", "disagrees"),
    "URDF joint type disagrees": ("microbo", "urdf/microbo.urdf", '<joint name="joint3" type="prismatic">',
                                  '<joint name="joint3" type="revolute">', "joint joint3", "data file says 'prismatic'"),
    "URDF mass disagrees": ("puma260", "urdf/puma260.urdf", '<mass value="0.75"/>', '<mass value="0.70"/>',
                            "link link6.inertial.mass", "disagrees"),
    "URDF com disagrees": ("puma260", "urdf/puma260.urdf", '<origin xyz="-0.16625508665 0 0.03"',
                           '<origin xyz="-0.166 0 0.03"', "link link2.inertial.origin", "disagrees"),
    "URDF alpha sign wrong": ("puma260", "urdf/puma260.urdf", '<origin xyz="0 0 0.12624" rpy="-1.5707963267948966 0 0"/>',
                              '<origin xyz="0 0 0.12624" rpy="1.5707963267948966 0 0"/>', "link link3",
                              "differs from DH frame 3"),
    "DH length changed without the URDF": ("puma260", "puma260.toml", "value = 126.24,", "value = 130.0,",
                                           "link link3", "differs from DH frame 3"),
    "URDF zero axis": ("microbo", "urdf/microbo.urdf", '<axis xyz="0 0 1"/>\n    <limit lower="0.2"',
                       '<axis xyz="0 0 0"/>\n    <limit lower="0.2"', "joint joint3.axis", "zero axis"),
    "URDF not XML": ("microbo", "urdf/microbo.urdf", "</robot>", "</robt>", "<file>", "not valid XML"),
    "grouping names differ from the coefficients": ("puma260", "puma260.toml", 'c15 = "-g*(m5*z5 + m6*z6)"',
                                                    'c16 = "-g*(m5*z5 + m6*z6)"', "gravity_grouping.meanings",
                                                    "differ from gravity_coeffs"),
    "grouping com_form short": ("microbo", "microbo.toml", '["0", "0", "z6"]]', ']', "gravity_grouping.com_form",
                                "list of 6 lists"),
    "published source without a reference": ("puma560", "puma560.toml",
                                              'source = "published [CA94] standard DH, a4" }',
                                              'source = "published" }', "joints.4.a", "neither"),
    "Panda: modified table not starting at the base frame": (
        "panda", "panda.toml", 'a = { value = 0.0, unit = "m", source = "published [FE] modified-DH (Craig) table, a0',
        'a = { value = 0.01, unit = "m", source = "published [FE] modified-DH (Craig) table, a0', "joints.1.a",
        "must start with a0 = alpha0 = 0"),
    "Panda: twisted flange": ("panda", "panda.toml", 'alpha = { value = 0.0, unit = "deg", source = "published [FE] '
                              'modified-DH (Craig) table, flange row', 'alpha = { value = 45.0, unit = "deg", source = '
                              '"published [FE] modified-DH (Craig) table, flange row', "flange.alpha", "must be 0"),
    "Panda: unknown DH convention": ("panda", "panda.toml", 'n_joints = 7\ndh = "modified"', 'n_joints = 7\ndh = "craig"', "robot.dh",
                                     "unknown DH convention 'craig'"),
    "Panda: missing flange": ("panda", "panda.toml", "\n[flange]\n", "\n[flange_row]\n", "<top level>",
                              "unknown key"),
    "Panda: effort limit for some joints only": ("panda", "panda.toml", 'max_effort = { value = 12.0, unit = "N*m", '
                                                 'source = "published [FE] limits for Panda, tau_j_max" }\n', '',
                                                 "joints.5.max_effort", "for every joint or for none"),
    "Panda: jerk in the wrong unit": ("panda", "panda.toml", 'max_jerk = { value = 7500.0, unit = "rad/s^3"',
                                      'max_jerk = { value = 7500.0, unit = "rad/s^2"', "joints.1.max_jerk", "wrong unit"),
    "PUMA 560 URDF elbow offset disagrees": ("puma560", "urdf/puma560.urdf", '<origin xyz="0.0203 0 0"',
                                             '<origin xyz="0.0 0 0"', "link link3", "differs from DH frame 3"),
}


@pytest.mark.parametrize("case", sorted(BROKEN))
def test_malformed_file_raises_model_error(case: str, tmp_path: Path) -> None:
    robot, target, old, new, field, problem = BROKEN[case]
    root = _copy_models(tmp_path)
    _edit(root / target, old, new)
    with pytest.raises(ModelError) as info:
        load_robot(root / f"{robot}.toml")
    err = info.value
    assert err.field == field, str(err)
    assert problem in err.problem, str(err)
    assert Path(err.path) in (root / f"{robot}.toml", root / "urdf" / f"{robot}.urdf"), str(err)
    assert str(err).startswith(f"{err.path}: {field}: ")


def test_missing_data_file_names_path(tmp_path: Path) -> None:
    with pytest.raises(ModelError) as info:
        load_robot(tmp_path / "nothing.toml")
    assert info.value.path == str(tmp_path / "nothing.toml") and info.value.field == "<file>"


def test_estimate_without_why_is_rejected(tmp_path: Path) -> None:
    root = _copy_models(tmp_path)
    _edit(root / "puma260.toml", 'source = "estimate"\nwhy = "folded rest pose: upper arm 40 deg below horizontal, '
          'forearm nearly vertical (theta2 + theta3 = -10 deg), wrist bent off its singularity; inside every joint range"',
          'source = "estimate"')
    with pytest.raises(ModelError, match=r"poses\.nest: estimate without 'why'"):
        load_robot(root / "puma260.toml")


# ----------------------------------------------------------------------------- modified DH (the Panda)

def _craig_step(a: float, alpha: float, d: float, theta: float) -> np.ndarray:
    """Craig's step Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i), written out independently."""
    ca, sa, ct, st = math.cos(alpha), math.sin(alpha), math.cos(theta), math.sin(theta)
    return np.array([[ct, -st, 0.0, a],
                     [st * ca, ct * ca, -sa, -sa * d],
                     [st * sa, ct * sa, ca, ca * d],
                     [0.0, 0.0, 0.0, 1.0]])


def _panda_craig_rows() -> list[tuple[float, float, float]]:
    """(a_{i-1}, alpha_{i-1}, d_i) as the data file carries them (Craig's rows, SI)."""
    import tomllib

    data = tomllib.loads((MODELS / "panda.toml").read_text())
    return [(j["a"]["value"], math.radians(j["alpha"]["value"]), j["d"]["value"]) for j in data["joints"]], data


def test_panda_standard_chain_is_the_craig_chain() -> None:
    """The loader's standard table reproduces the published modified-DH chain: the origin of
    every standard frame k lies on Craig frame k's joint axis ... exactly where Craig frame k
    moved by its shift puts it, the flange is frame 7, and the links' centres of mass land at
    the same points of the base frame."""
    panda = load_robot("panda")
    rows, data = _panda_craig_rows()
    flange_d = data["flange"]["d"]["value"]
    assert panda.dh_convention == "modified" and panda.n_joints == 7
    for q in np.random.default_rng(3).uniform(panda.lower, panda.upper, size=(50, 7)):
        craig = np.eye(4)
        std = panda.base_to_link(q)
        for k, ((a, alpha, d), qk) in enumerate(zip(rows, q)):
            craig = craig @ _craig_step(a, alpha, d, qk)
            # the joint axis of Craig frame k is z_k; standard frame k-1's z is the same axis
            z_std = std[k - 1][:3, 2] if k else np.array([0.0, 0.0, 1.0])
            assert np.allclose(z_std, craig[:3, 2], atol=1e-12)
            assert np.allclose(std[k], craig @ panda.data_frames[k], atol=1e-12)
            com = np.asarray(data["links"][k]["com"]["values"])
            com_base_craig = craig[:3, :3] @ com + craig[:3, 3]
            com_base_std = std[k][:3, :3] @ panda.links[k].com + std[k][:3, 3]
            assert np.allclose(com_base_craig, com_base_std, atol=1e-12)
        flange = craig.copy()
        flange[:3, 3] += flange_d * craig[:3, 2]
        assert np.allclose(std[6], flange, atol=1e-12)


def test_panda_zero_pose_and_limits() -> None:
    """At q = 0 the arm stands straight up with the 8.25 cm elbow offset cancelled and the
    flange 8.8 cm forward: (a6, 0, d1 + d3 + d5 - d_F) in Craig's numbering."""
    panda = load_robot("panda")
    rows, data = _panda_craig_rows()
    a_wrist = rows[6][0]
    height = rows[0][2] + rows[2][2] + rows[4][2] - data["flange"]["d"]["value"]
    t7 = panda.base_to_link(np.zeros(7))[6]
    assert t7[:3, 3] == pytest.approx([a_wrist, 0.0, height], abs=1e-12)
    assert t7[:3, 2] == pytest.approx([0.0, 0.0, -1.0], abs=1e-12)  # flange pointing down
    assert panda.max_effort == pytest.approx([87, 87, 87, 87, 12, 12, 12])
    assert panda.max_acceleration.shape == panda.max_jerk.shape == (7,)
    assert np.all(panda.max_jerk > panda.max_acceleration) and np.all(panda.max_acceleration > panda.max_velocity)
    # the current limit reaches the published torque: max_current x sigma x G = tau_max
    g = np.diag(panda.conversion.gear_ratio.values)
    assert panda.max_current * panda.motors.torque_sensitivity.values * g == pytest.approx(panda.max_effort)
    assert panda.source("links.3.mass").tag.startswith("published [GAZ]")
    assert panda.source("joints.4.a").tag.startswith("published [FE]")
