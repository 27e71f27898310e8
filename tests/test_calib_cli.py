"""The calib command on real recorder files: tables, parameter file, plots, bad input."""
from __future__ import annotations

import os

import numpy as np
import pytest

from rcci.calib.__main__ import main
from rcci.calib.params import read_params
from tests.test_calib_synth import SIGMA, drive, friction_torque, sweep, to_trace, write_rcilog
from tests.test_calib_fits import FC_M, FC_P, FV_M, FV_P, rates


def sigma_params(tmp_path, name: str = "fitted.toml", sigma=SIGMA) -> str:
    """A parameter file holding fitted torque sensitivities (as `calib fit sensitivity` writes),
    which the friction fit needs."""
    from rcci.calib.params import update_params

    path = str(tmp_path / name)
    update_params(path, "puma260", {"motors": {"torque_sensitivity": [float(x) for x in sigma]}}, "test")
    return path


def _friction_log(tmp_path, joint: int, robot: str = "puma260", meta_extra=None, name=None) -> str:
    rng = np.random.default_rng(joint)
    t, q = sweep(np.zeros(6), joint - 1, -0.5, 0.5, [0.1, 0.4, 0.8, 1.2])
    tau = friction_torque(rates(t, q), FC_P, FC_M, FV_P, FV_M)
    meta = {"experiment": "friction", "joint": joint, "window": [-0.5, 0.5]}
    meta.update(meta_extra or {})
    tr = to_trace(t, q, tau, meta, drive(), rng)
    return write_rcilog(str(tmp_path / (name or f"friction-j{joint}-{robot}.rcilog")), tr, robot)


def test_fit_friction_prints_table_writes_params_and_plots(tmp_path, capsys):
    logs = [_friction_log(tmp_path, j) for j in (1, 5)]
    params = sigma_params(tmp_path)
    rc = main(["fit", "friction", *logs, "--params", params, "--plots", str(tmp_path), "-q"])
    out = capsys.readouterr().out
    assert rc == 0, out
    assert "Table 4.2" in out and "Table 4.3" in out
    data = read_params(params)
    assert data["calib"]["robot"] == "puma260"
    assert data["friction"]["coulomb_pos"][0] == pytest.approx(FC_P[0], abs=0.03)
    assert data["friction"]["coulomb_neg"][4] == pytest.approx(FC_M[4], abs=0.01)
    assert os.path.getsize(tmp_path / "calib-friction-j1.png") > 1000
    # joints not fitted are NaN (not fitted), not the data file's Table 4.2 (issue 14, item 2)
    assert np.isnan(data["friction"]["coulomb_pos"][1])
    assert "static_pos" not in data["friction"]          # Table 4.5 is not copied (item 3)


def test_truncated_log_names_file_and_record(tmp_path, capsys):
    log = _friction_log(tmp_path, 1)
    data = open(log, "rb").read()
    open(log, "wb").write(data[: len(data) - 700])
    rc = main(["fit", "friction", log, "-q"])
    err = capsys.readouterr().err
    assert rc == 2
    assert log in err and "truncated after record" in err


def test_corrupt_block_names_file_and_records(tmp_path, capsys):
    log = _friction_log(tmp_path, 1)
    data = bytearray(open(log, "rb").read())
    data[len(data) // 2] ^= 0xFF
    open(log, "wb").write(bytes(data))
    rc = main(["fit", "friction", log, "-q"])
    err = capsys.readouterr().err
    assert rc == 2
    assert log in err and "records" in err and "checksum" in err


def test_mixed_robots_are_refused(tmp_path, capsys):
    a = _friction_log(tmp_path, 1)
    b = _friction_log(tmp_path, 2, robot="microbo")
    rc = main(["fit", "friction", a, b, "-q"])
    err = capsys.readouterr().err
    assert rc == 2 and "different robots" in err and b in err


def test_missing_metadata_is_named(tmp_path, capsys):
    log = _friction_log(tmp_path, 1, meta_extra={"window": None})
    rc = main(["fit", "friction", log, "-q", "-p", sigma_params(tmp_path)])
    err = capsys.readouterr().err
    assert rc == 2 and log in err and "'window'" in err


def test_wrong_kind_of_log_is_named(tmp_path, capsys):
    log = _friction_log(tmp_path, 1)
    rc = main(["fit", "gravity", log, "-q"])
    err = capsys.readouterr().err
    assert rc == 2 and log in err and "not a 'gravity'" in err


def test_failed_fit_leaves_previous_parameters_untouched(tmp_path, capsys):
    params = sigma_params(tmp_path)
    assert main(["fit", "friction", _friction_log(tmp_path, 1), "--params", params, "-q"]) == 0
    before = open(params, "rb").read()
    bad = _friction_log(tmp_path, 2, name="bad.rcilog")
    data = open(bad, "rb").read()
    open(bad, "wb").write(data[:-900])
    assert main(["fit", "friction", bad, "--params", params, "-q"]) == 2
    assert open(params, "rb").read() == before
    assert [f for f in os.listdir(tmp_path) if f.endswith(".tmp")] == []


def test_gzipped_log_fits_like_the_plain_one(tmp_path, capsys):
    import gzip
    log = _friction_log(tmp_path, 1)
    gz = log + ".gz"
    with open(log, "rb") as f, gzip.open(gz, "wb") as g:
        g.write(f.read())
    p = sigma_params(tmp_path)
    assert main(["fit", "friction", log, "-q", "-p", p]) == 0
    plain = capsys.readouterr().out
    assert main(["fit", "friction", gz, "-q", "-p", p]) == 0
    assert capsys.readouterr().out.replace(".gz", "") .splitlines()[2:-1] == plain.splitlines()[2:-1]
    open(gz, "wb").write(open(gz, "rb").read()[:-50])
    assert main(["fit", "friction", gz, "-q", "-p", p]) == 2
    assert gz in capsys.readouterr().err


def test_runtime_loads_fitted_values_and_keeps_the_rest_nominal(tmp_path, capsys):
    from rcci.calib.exceptions import CalibError
    from rcci.calib.params import load_fitted

    params = sigma_params(tmp_path)
    assert main(["fit", "friction", _friction_log(tmp_path, 3), "--params", params, "-q"]) == 0
    fitted = load_fitted(params, "puma260")
    nominal = load_fitted(None, "puma260")
    assert fitted.coulomb_pos[2] == pytest.approx(FC_P[2], abs=0.03)
    assert fitted.coulomb_pos[2] != nominal.coulomb_pos[2]
    np.testing.assert_array_equal(fitted.coulomb_pos[[0, 1, 3, 4, 5]], nominal.coulomb_pos[[0, 1, 3, 4, 5]])
    np.testing.assert_array_equal(fitted.sigma, nominal.sigma)
    # what is the data file's and not fitted is named, for a program to print
    assert "friction.coulomb_pos[1]" in fitted.assumed and "friction.coulomb_pos[3]" not in fitted.assumed
    assert "gravity_coeffs.c12" in fitted.assumed
    with pytest.raises(CalibError, match="not 'microbo'"):
        load_fitted(params, "microbo")


def test_repeated_cycle_number_names_the_record(tmp_path, capsys):
    from rci.how import How
    from rci.recorder import Recorder

    path = str(tmp_path / "dup.rcilog")
    with Recorder(path, robot="puma260", meta={"experiment": "friction", "joint": 1,
                                              "window": [-0.5, 0.5]}) as rec:
        for k, cycle in enumerate([0, 1, 2, 2, 3]):
            rec.append(How(pos=np.zeros(6, dtype=np.int64), adcr=np.zeros(16, dtype=np.int64),
                           cycle=cycle, rate_hz=36), None)
    assert main(["fit", "friction", path, "-q"]) == 2
    err = capsys.readouterr().err
    assert f"{path}: record 3: cycle 2 repeats" in err


def test_log_without_run_metadata_is_refused(tmp_path, capsys):
    from rci.how import How
    from rci.recorder import Recorder

    path = str(tmp_path / "bare.rcilog")
    with Recorder(path, robot="puma260") as rec:
        rec.append(How(cycle=0), None)
    assert main(["fit", "static", path, "-q"]) == 2
    assert "metadata 'experiment'" in capsys.readouterr().err


def test_xz_log_fits_like_the_plain_one(tmp_path, capsys):
    """calib/logs/ ships xz-compressed logs; a truncated one is refused by name."""
    import lzma
    log = _friction_log(tmp_path, 1)
    xz = log + ".xz"
    with open(log, "rb") as f, lzma.open(xz, "wb") as g:
        g.write(f.read())
    p = sigma_params(tmp_path)
    assert main(["fit", "friction", log, "-q", "-p", p]) == 0
    plain = capsys.readouterr().out
    assert main(["fit", "friction", xz, "-q", "-p", p]) == 0
    assert capsys.readouterr().out.replace(".xz", "").splitlines()[2:-1] == plain.splitlines()[2:-1]
    open(xz, "wb").write(open(xz, "rb").read()[:-50])
    assert main(["fit", "friction", xz, "-q", "-p", p]) == 2
    assert xz in capsys.readouterr().err
