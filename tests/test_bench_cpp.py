"""make bench's C++ comparison (bench/cpp_pinocchio.py): the program builds against the pin
wheel, and Pinocchio's C++ and the generated kernels it links compute the same T6, 6J, 4J and
gravity. Correctness only; the speeds are make bench's. The first run compiles the C++ side
(about a minute of CPU); later runs reuse build/bench/."""
from __future__ import annotations

import math
import sysconfig

import numpy as np
import pytest

from bench import cpp_pinocchio

ROBOTS = cpp_pinocchio.robots()


def test_every_robot_with_kernels_is_compared():
    assert {"puma260", "microbo"} <= set(ROBOTS)


@pytest.mark.parametrize("robot", ROBOTS)
def test_pinocchio_cpp_agrees_with_the_generated_kernels(robot):
    mod = __import__(f"rccl.kinematics.{robot}", fromlist=["x"])
    rng = np.random.default_rng(5)
    q = np.vstack([np.zeros(6), cpp_pinocchio.random_q(robot, 11, rng)])
    run = cpp_pinocchio.run(robot, q, repeats=1, with_results=True)
    assert run.n == len(q)
    tol = {"fk": 1e-12, "jacobian6": 1e-12, "jacobian4": 1e-12, "gravity": 1e-10}
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
    assert "Pinocchio's headers" in msg and "urdf_model/model.h" in msg and "cmeel-urdfdom-headers" in msg


def test_bad_configurations_are_refused():
    with pytest.raises(ValueError, match="N x 6"):
        cpp_pinocchio.run(ROBOTS[0], np.zeros((3, 5)))
