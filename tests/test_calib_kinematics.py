"""The kinematic error fit of 3.83-3.84 on synthetic measured poses with known errors."""
from __future__ import annotations

import numpy as np

from rcci.calib.__main__ import main
from rcci.calib.kinematics import fit_kinematics, fk_function
from rcci.models import load_robot

MODEL = load_robot("puma260")
DH = np.array([[j.theta, j.d, j.a, j.alpha] for j in MODEL.joints])
SCALE = np.tile([np.radians(0.1), 0.0005, 0.0005, np.radians(0.1)], 6)


def _poses(n: int, noise: bool, seed: int = 0):
    rng = np.random.default_rng(seed)
    e_true = rng.normal(0, 1, 24) * SCALE
    T6 = fk_function(DH)
    Q = rng.uniform(MODEL.lower, MODEL.upper, size=(n, 6))
    poses = np.array([np.array(T6(q, e_true)) for q in Q])
    if noise:
        for P in poses:
            P[:3, 3] += rng.normal(0, 5e-5, 3)
            w = rng.normal(0, np.radians(0.005), 3)
            K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
            P[:3, :3] = P[:3, :3] @ (np.eye(3) + K)  # first order is enough at 1e-4 rad
    return Q, poses, e_true


def test_recovers_identifiable_errors_and_names_the_parallel_axis_pair():
    Q, poses, e_true = _poses(40, noise=True)
    fit = fit_kinematics(DH, Q, poses)
    assert fit.rank == 23
    # d d2 and d d3 move the arm along the same direction (axes 2 and 3 are parallel)
    assert set(np.flatnonzero(~fit.identifiable)) == {5, 9}
    err = np.abs(fit.e - e_true)[fit.identifiable]
    assert (err <= 4 * fit.std[fit.identifiable] + 1e-9).all()
    assert abs((fit.e[5] + fit.e[9]) - (e_true[5] + e_true[9])) < 5e-5
    assert fit.rms_position_after < 1e-4 < fit.rms_position_before


def test_command_reads_poses_and_reports_bad_lines(tmp_path, capsys):
    Q, poses, _ = _poses(30, noise=False, seed=3)
    lines = []
    for q, P in zip(Q, poses):
        R = P[:3, :3]
        angle = np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))
        w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) * angle / (2 * np.sin(angle))
        lines.append(",".join(f"{x:.12g}" for x in (*q, *P[:3, 3], *w)))
    good = tmp_path / "poses.csv"
    good.write_text("# q1..q6, x, y, z, rx, ry, rz\n" + "\n".join(lines) + "\n")
    assert main(["fit", "kinematics", str(good)]) == 0
    out = capsys.readouterr().out
    assert "rank 23 of 24" in out and "not separable" in out
    bad = tmp_path / "bad.csv"
    bad.write_text(lines[0] + "\n1,2,3\n")
    assert main(["fit", "kinematics", str(bad)]) == 2
    assert f"{bad}: record 2" in capsys.readouterr().err


def test_pose_files_of_another_arm_take_robot(tmp_path, capsys):
    """Pose files name no arm: `--robot puma560` fits them with the PUMA 560's table (and says
    so); without it the output names the PUMA 260 it assumed, which does not fit them."""
    from rcci.calib.params import read_params

    m = load_robot("puma560")
    dh = np.array([[j.theta, j.d, j.a, j.alpha] for j in m.joints])
    rng = np.random.default_rng(8)
    e_true = rng.normal(0, 1, 24) * SCALE
    T6 = fk_function(dh)
    lines = []
    for q in rng.uniform(m.lower, m.upper, size=(30, 6)):
        P = np.array(T6(q, e_true))
        R = P[:3, :3]
        angle = np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))
        w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) * angle / (2 * np.sin(angle))
        lines.append(",".join(f"{x:.12g}" for x in (*q, *P[:3, 3], *w)))
    poses = tmp_path / "poses560.csv"
    poses.write_text("\n".join(lines) + "\n")
    params = tmp_path / "fitted.toml"
    assert main(["fit", "kinematics", str(poses), "--robot", "puma560", "-p", str(params)]) == 0
    out = capsys.readouterr().out
    assert "of robot puma560 (--robot)" in out
    assert read_params(str(params))["calib"]["robot"] == "puma560"
    assert main(["fit", "kinematics", str(poses), "-p", str(params)]) == 2      # the file is the PUMA 560's
    assert "holds parameters of robot 'puma560'" in capsys.readouterr().err
    assert main(["fit", "kinematics", str(poses)]) == 0
    assert "of robot puma260 (the default; --robot names another arm)" in capsys.readouterr().out
