"""derive.dynamics_base: the symbolic grouping of the 66 standard parameters into the base
parameters is exact (the full regressor times random standard parameters equals the base
regressor times their groups) and minimal (the base columns have full rank)."""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from derive.dynamics import rotor_params, standard_params
from derive.dynamics_base import numeric_columns, base_parameters
from derive.robots import load_spec

ROBOTS = ("puma260", "microbo", "puma560", "stanford")


@pytest.mark.parametrize("robot", ROBOTS)
def test_grouping_is_exact_and_minimal(robot: str) -> None:
    spec = load_spec(robot)
    bp = base_parameters(spec.dh, spec.params)
    assert len(set(bp.names)) == len(bp.names)
    n = len(spec.dh.links)
    full = list(standard_params(n)) + list(rotor_params(n))
    y_full = numeric_columns(spec.dh, full, spec.params, n=10, seed=11)
    y_base = numeric_columns(spec.dh, list(bp.leaders), spec.params, n=10, seed=11)
    rng = np.random.default_rng(0)
    phi = rng.normal(size=len(full))
    values = dict(zip(full, phi))
    values.update({k: float(v) for k, v in spec.params.items()})
    beta = np.array([float(sp.sympify(m).xreplace(values)) for m in bp.meanings])
    lhs, rhs = y_full @ phi, y_base @ beta
    assert np.abs(lhs - rhs).max() <= 1e-9 * max(1.0, np.abs(lhs).max())
    s = np.linalg.svd(y_base, compute_uv=False)
    assert s[-1] > 1e-8 * s[0], f"{robot}: base columns are rank deficient"


def test_puma_base_parameters_are_the_classic_set() -> None:
    """The PUMA's 36 rigid-body base parameters (Khalil's count for this geometry) plus the
    rotors of joints 3-6; the rotors of joints 1 and 2 join ZZ1R and ZZ2R."""
    bp = base_parameters(load_spec("puma260").dh, load_spec("puma260").params)
    assert len(bp.names) == 40
    assert {"ZZ1R", "XX2R", "MX2R", "IA3", "IA6"} <= set(bp.names)
    assert "IA1" not in bp.names and "IA2" not in bp.names
    assert set(bp.dropped) == {"XX1", "XY1", "XZ1", "YZ1", "MX1", "MY1"}
