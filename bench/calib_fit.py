"""Benchmark: time `calib fit` on a 10-minute log (target: under 2 s per fit).

Run:  .venv/bin/python bench/calib_fit.py [--minutes 10] [--rate 36]

Writes 10-minute friction and static-friction logs (36 Hz, real recorder files) from the
measurement programs' own paths with the thesis's friction and gravity as the torques,
then times reading + fitting each, in this process, best of three; also the shipped
joint-5 friction logs (one of them read at 1 kHz).
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from rcci.calib.experiments import friction_plans, static_plan
from rcci.calib.fitting import run_fit
from rcci.calib.logs import load_trace
from rcci.calib.robot import robot_info
from rci.conversions import Conversions, friction_torque
from rci.how import How
from rci.recorder import Recorder


def _write(path: Path, q: np.ndarray, rate: float, meta: dict, info, conv: Conversions,
           rng: np.random.Generator) -> int:
    nom = info.nominal["friction"]
    qd = np.gradient(q, 1.0 / rate, axis=0)
    tau = friction_torque(qd, *(np.array(nom[k]["values"]) for k in
                                ("coulomb_pos", "coulomb_neg", "viscous_pos", "viscous_neg")))
    c = np.array([info.nominal["gravity_coeffs"][n]["value"] for n in ("c12", "c13", "c15")])
    tau += np.einsum("nij,j->ni", np.array([info.regressor(x) for x in q]), c)
    adc = conv.joint_torques_to_adc(tau) + rng.normal(0, 1.0, tau.shape)
    counts = conv.angles_to_counts_int(q)
    with Recorder(path, robot="puma260", rate_hz=int(rate), meta=meta) as rec:
        for k in range(len(q)):
            a = np.zeros(16, dtype=np.int64)
            a[:6] = np.clip(np.rint(adc[k]), -2048, 2047)
            rec.append(How(pos=counts[k], adcr=a, cycle=k, time_ns=int(k * 1e9 / rate),
                           rate_hz=int(rate)), None)
            if k % 4096 == 4095:
                rec.flush()
    return len(q)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--rate", type=float, default=36.0)
    args = ap.parse_args()
    info = robot_info("puma260")
    conv = Conversions.for_robot("puma260")
    rng = np.random.default_rng(0)
    n_target = int(args.minutes * 60 * args.rate)
    with tempfile.TemporaryDirectory() as tmp:
        (plan,) = friction_plans([2], trips=1)
        q = plan.path.sample(args.rate)
        q = np.vstack([q] * (n_target // len(q) + 1))[:n_target]
        f_log = Path(tmp) / "friction.rcilog"
        _write(f_log, q, args.rate, plan.meta, info, conv, rng)
        splan = static_plan(info.lower, info.upper, halts=2000)
        q = splan.path.sample(args.rate)[:n_target]
        s_log = Path(tmp) / "static.rcilog"
        _write(s_log, q, args.rate, splan.meta, info, conv, rng)
        print(f"calib fit on {args.minutes:g}-minute logs at {args.rate:g} Hz "
              f"({n_target} records each; target < 2 s)")
        for kind, log in (("friction", f_log), ("static", s_log)):
            best = np.inf
            for _ in range(3):
                t0 = time.perf_counter()
                tr = load_trace(str(log))
                out = run_fit(kind, [tr], info, None, assume_datafile=True)   # the synthetic logs are the data file's arm
                best = min(best, time.perf_counter() - t0)
            size = log.stat().st_size / 1e6
            print(f"  {kind:9s} {len(tr.t):6d} records, {size:5.1f} MB: read + fit {best:6.3f} s "
                  f"({'OK' if best < 2.0 else 'SLOW'})")
            del out
    # the shipped joint-5 logs, whose fast passes are read at every servo tick (1 kHz)
    from rcci.calib.logs import LOG_DIR
    from rcci.calib.logs import load_traces

    j5 = sorted(str(p) for p in Path(LOG_DIR).glob("friction-j5*.rcilog.*"))
    if j5:
        best = np.inf
        for _ in range(3):
            t0 = time.perf_counter()
            trs = load_traces(j5)
            run_fit("friction", trs, info, None, assume_datafile=True)
            best = min(best, time.perf_counter() - t0)
        n = sum(len(t.t) for t in trs)
        print(f"  friction  {n:6d} records in the shipped joint-5 logs (72 Hz + 1 kHz): "
              f"read + fit {best:6.3f} s")


if __name__ == "__main__":
    main()
