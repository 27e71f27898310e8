"""make bench's C++ comparison (bench/cpp_pinocchio.py): the program builds against the pin
wheel, and Pinocchio's C++ (on the model its URDF parser builds) and the generated kernels it
links compute the same T6, 6J, 4J, gravity, inverse dynamics and inertia matrix, for every arm
of any joint count (the Panda's seven: its program compiled with -DNJ=7 and frame link7). Correctness only; the speeds are make bench's,
so the program is the CHECK build (Pinocchio's side without optimisation, on the wheel's
compiled algorithms, its own cache build/bench/check/): the first run compiles it, about a
third of the CPU of make bench's build; later runs reuse it."""
from __future__ import annotations

import math
import sysconfig

import numpy as np
import pytest

import rccl.kinematics
from bench import cpp_pinocchio

ROBOTS = cpp_pinocchio.robots()
#: the default suite's robot (the first, as the model-file test below): the Pinocchio object and
#: this robot's kernels are compiled once; every other robot's kernels (a -O3 compile each, about
#: 20 s at load 8) run under ``-m slow``
DEFAULT_ROBOT = ROBOTS[0]


def test_every_robot_with_kernels_is_compared():
    assert {"puma260", "microbo", "puma560", "panda"} <= set(ROBOTS)


def test_the_results_layout_and_configurations_are_sized_by_the_joint_count():
    assert cpp_pinocchio.result_layout(6) == cpp_pinocchio.RESULT_LAYOUT
    assert dict(cpp_pinocchio.result_layout(7)) == {"fk": 16, "jacobian6": 42, "jacobian4": 42, "gravity": 7,
                                                    "inverse_dynamics": 7, "inertia_matrix": 49}
    assert cpp_pinocchio.joint_count("panda") == 7 and cpp_pinocchio.end_frame(7) == "link7"
    q = cpp_pinocchio.random_q("panda", 5, np.random.default_rng(1))
    lower, upper = np.asarray(rccl.kinematics.load("panda").LOWER), np.asarray(rccl.kinematics.load("panda").UPPER)
    assert q.shape == (5, 7) and np.all(q >= lower) and np.all(q <= upper)
    assert cpp_pinocchio.robot_defines(7) == ["-DNJ=7", '-DEND_FRAME="link7"']
    text = cpp_pinocchio.model_text("panda")
    assert [line.split()[:2] for line in text.splitlines() if line.startswith("frame")] == [["frame", "link4"],
                                                                                           ["frame", "link7"]]
    assert sum(line.startswith("joint") for line in text.splitlines()) == 7


@pytest.mark.parametrize("robot", [pytest.param(r, marks=() if r == DEFAULT_ROBOT else pytest.mark.slow)
                                   for r in ROBOTS])
def test_pinocchio_cpp_agrees_with_the_generated_kernels(robot):
    """The default suite compares the first robot (the microbo: revolute and prismatic joints,
    the Pinocchio object's compile and one kernel build); ``-m slow`` adds the PUMA 260, PUMA 560
    and Stanford arms, each its own -O3 kernel compile and link, and the seven-joint Panda (its
    own Pinocchio object too, -DNJ=7)."""
    mod = rccl.kinematics.load(robot)
    rng = np.random.default_rng(5)
    q = np.vstack([np.zeros(cpp_pinocchio.joint_count(robot)), cpp_pinocchio.random_q(robot, 11, rng)])
    run = cpp_pinocchio.run(robot, q, repeats=1, with_results=True, profile=cpp_pinocchio.CHECK)
    assert run.n == len(q)
    tol = {"fk": 1e-12, "jacobian6": 1e-12, "jacobian4": 1e-12, "gravity": 1e-10,
           "inverse_dynamics": 1e-10, "inertia_matrix": 1e-12}
    for name, (pin, kernel) in run.results.items():
        err = np.abs(pin - kernel).max()
        assert err < tol[name], f"{robot} {name}: Pinocchio C++ and the generated kernel differ by {err:.2e}"
    # the program's kernels are the extension's: same results as the Python-facing calls
    ext = {"fk": mod.fk(q), "jacobian6": mod.jacobian6(q), "jacobian4": mod.jacobian4(q),
           "gravity": mod.gravity(q, cpp_pinocchio.gravity_coefficients(robot))}
    for name, want in ext.items():
        np.testing.assert_allclose(run.results[name][1], want.reshape(len(q), -1), rtol=0, atol=1e-14,
                                   err_msg=f"{robot} {name}: standalone kernel vs rccl.kinematics")
    # every computation timed on both sides (values are make bench's business)
    assert set(run.ns) == {(op, side) for op in cpp_pinocchio.OPS for side in ("pinocchio", "c_one", "c_rows")}
    assert all(math.isfinite(t) and t > 0 for t in run.ns.values())


def test_missing_headers_are_named(monkeypatch, tmp_path):
    real = sysconfig.get_paths()
    monkeypatch.setattr(sysconfig, "get_paths", lambda: {**real, "purelib": str(tmp_path)})
    with pytest.raises(cpp_pinocchio.ToolchainError) as err:
        cpp_pinocchio.toolchain()
    msg = str(err.value)
    assert "Pinocchio's headers" in msg and "libpinocchio_default.so" in msg


def test_bad_configurations_are_refused():
    with pytest.raises(ValueError, match="N x 6"):
        cpp_pinocchio.run(ROBOTS[0], np.zeros((3, 5)), profile=cpp_pinocchio.CHECK)
    with pytest.raises(ValueError, match="N x 7 \\(panda's joints\\)"):
        cpp_pinocchio.run("panda", np.zeros((3, 6)), profile=cpp_pinocchio.CHECK)


def test_the_model_file_is_pinocchios_model_and_bad_lines_are_named(tmp_path):
    import subprocess

    robot = ROBOTS[0]
    text = cpp_pinocchio.model_text(robot)
    kinds = [line.split()[0] for line in text.splitlines()]
    assert kinds == ["joint"] * 6 + ["frame", "frame"]
    exe = cpp_pinocchio.build(robot, profile=cpp_pinocchio.CHECK)
    q, c = tmp_path / "q.bin", tmp_path / "c.bin"
    np.zeros((1, 6)).tofile(q)
    cpp_pinocchio.gravity_coefficients(robot).tofile(c)
    bad = tmp_path / "model.txt"
    bad.write_text(text.replace(text.split()[2], "JointModelSpherical", 1))
    r = subprocess.run([str(exe), str(bad), str(q), str(c), "1"], capture_output=True, text=True)
    assert r.returncode == 1 and "joint type JointModelSpherical is not one this program rebuilds" in r.stderr
    bad.write_text(text + "frame link7 6 1 0 0\n")
    r = subprocess.run([str(exe), str(bad), str(q), str(c), "1"], capture_output=True, text=True)
    assert r.returncode == 1 and f"{bad}:9: not a frame line" in r.stderr
