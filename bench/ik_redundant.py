"""`python -m bench.ik_redundant`: speed of the Panda's closed-form inverse with q7 free
(``rccl.kinematics.load("panda")``), against Pinocchio's forward kinematics of the same arm
measured in the same run; writes reports/ik-redundant.md.

Rows: the compiled ``ik_all`` kernel through its Python binding (every branch of one pose and
one q7, guards included, no range filter); the public ``ik_all(T, q7)`` and ``ik(T, config,
q7=...)`` (kernel + joint ranges + the fk check that every solution reproduces T + duplicates
removed: the C fast entry, rccl/kinematics/_c/kin_redundant.h); the same two through the
Python runtime (the fallback, RedundantRobot's methods, numpy); the batched kernel per pose. Per-call figures are medians and 99th percentiles of single
timed calls (time.perf_counter_ns), after a warm-up.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from rcci.models import load_robot  # noqa: E402
from rccl.kinematics import backend  # noqa: E402

COMMAND = "python -m bench.ik_redundant"


def timed(fn, n: int) -> tuple[float, float]:
    """(median, p99) in microseconds of ``n`` single calls of ``fn`` after 200 warm-up calls."""
    for _ in range(200):
        fn()
    ts = np.empty(n)
    clock = time.perf_counter_ns
    for i in range(n):
        t0 = clock()
        fn()
        ts[i] = clock() - t0
    return float(np.median(ts)) / 1e3, float(np.percentile(ts, 99)) / 1e3


def measure(n_calls: int, n_batch: int, seed: int = 11) -> dict:
    import rccl.kinematics as kin

    mod = kin.load("panda")
    robot = importlib.import_module("rccl.kinematics.panda")._ROBOT
    cm = backend.c_module("panda")
    if cm is None or mod.ik_all == robot.ik_all:
        raise SystemExit("bench: the compiled panda kernels are missing or stale: `pip install -e .`")
    rng = np.random.default_rng(seed)
    qs = rng.uniform(mod.LOWER, mod.UPPER, size=(max(n_batch, 1000), 7))
    ts = cm.fk(qs)[0]
    q, t = qs[0], ts[0]
    q7 = np.float64(q[6])
    out: dict = {}
    out["c_ik_all"] = timed(lambda: cm.ik_all(t, q7), n_calls)
    out["public_ik_all"] = timed(lambda: mod.ik_all(t, q7), n_calls)
    out["n_solutions"] = len(mod.ik_all(t, q7))
    # the pose with the most solutions in range among the first 1000 drawn: the C entry's
    # fk checks, range moves and list grow with the solutions returned
    most = max(range(1000), key=lambda i: len(mod.ik_all(ts[i], qs[i, 6])))
    t_m, q7_m = ts[most], np.float64(qs[most, 6])
    out["n_most"] = len(mod.ik_all(t_m, q7_m))
    out["public_ik_all_most"] = timed(lambda: mod.ik_all(t_m, q7_m), n_calls)
    cfg = mod.config_of(q)
    out["public_ik"] = timed(lambda: mod.ik(t, cfg, q7=q7), n_calls)
    out["python_ik_all"] = timed(lambda: robot.ik_all(t, q7), n_calls // 20)
    out["python_ik"] = timed(lambda: robot.ik(t, cfg, q7=q7), n_calls // 20)
    out["c_fk"] = timed(lambda: cm.fk(q), n_calls)
    model = pin.buildModelFromUrdf(str(load_robot("panda").urdf_path))
    data = model.createData()
    fid = model.getFrameId("link7")

    def pin_fk():
        pin.framesForwardKinematics(model, data, q)
        return data.oMf[fid]

    out["pin_fk"] = timed(pin_fk, n_calls)
    small = 100  # below the size the C runtime splits over threads
    ts_s, vs_s = ts[:small].copy(), qs[:small, 6].copy()
    per = [0.0] * 200
    for i in range(len(per)):
        t0 = time.perf_counter()
        cm.ik_all(ts_s, vs_s)
        per[i] = (time.perf_counter() - t0) / small * 1e6
    out["c_ik_all_small"] = (float(np.median(per)), small)
    tb, vb = ts[:n_batch], qs[:n_batch, 6].copy()
    cm.ik_all(tb, vb)
    t0 = time.perf_counter()
    qa, ga = cm.ik_all(tb, vb)[:2]
    out["c_ik_all_batch"] = (time.perf_counter() - t0) / n_batch * 1e6
    out["threads"] = cm.threads()
    valid = (ga >= 0).all(axis=-1)
    back = cm.fk(qa[valid])[0]
    out["valid_per_pose"] = float(valid.sum(axis=1).mean())
    out["max_err"] = float(np.abs(back - np.broadcast_to(tb[:, None], qa.shape[:2] + (4, 4))[valid]).max())
    found = np.abs((qa - qs[:n_batch, None] + np.pi) % (2 * np.pi) - np.pi).max(axis=-1) < 1e-9
    out["drawn_found"] = float((found & valid).any(axis=1).mean())
    out["n_batch"] = n_batch
    out["n_calls"] = n_calls
    return out


def report(m: dict, seconds: float, load: tuple[float, float], command: str = COMMAND) -> str:
    def row(name, key, entry):
        med, p99 = m[key]
        return f"| {name} | {entry} | {med:.2f} | {p99:.2f} |"

    lines = [
        "# The Panda's closed-form inverse kinematics with q7 free", "",
        f"Written by `{command}` ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
        f"{seconds:.0f} s, load average {load[0]:.1f} at the start and {load[1]:.1f} at the end on "
        f"{os.cpu_count()} cores). Per-call figures: median and 99th percentile of "
        f"{m['n_calls']} single calls (the Python runtime's: {m['n_calls'] // 20}), microseconds.", "",
        "| computation | entry point | median (us) | p99 (us) |",
        "|---|---|---|---|",
        row("Panda ik_all, one pose and one q7, from Python: every branch (8) with guards",
            "c_ik_all", "compiled kernel `backend.c_module('panda').ik_all(T, q7)`"),
        row("Panda ik_all, one pose and one q7: solutions in range, fk-checked, distinct (public, C entry)",
            "public_ik_all", "`rccl.kinematics.load('panda').ik_all(T, q7)`"),
        row(f"Panda ik_all, the pose with the most solutions ({m['n_most']}) of 1000 drawn (public, C entry)",
            "public_ik_all_most", "`rccl.kinematics.load('panda').ik_all(T, q7)`"),
        row("Panda ik, one configuration, fk-checked (public, C entry)", "public_ik",
            "`rccl.kinematics.load('panda').ik(T, config, q7=...)`"),
        row("Panda ik_all, the same checks in the Python runtime (fallback)", "python_ik_all",
            "`rccl.kinematics.panda._ROBOT.ik_all(T, q7)`"),
        row("Panda ik, the same checks in the Python runtime (fallback)", "python_ik",
            "`rccl.kinematics.panda._ROBOT.ik(T, config, q7=...)`"),
        row("Panda fk (flange)", "c_fk", "compiled kernel `fk(q)`"),
        row("Panda fk (flange), Pinocchio, same run", "pin_fk",
            "`pin.framesForwardKinematics` + `oMf[link7]`"),
        "",
        f"The timed pose (fk of a q drawn in the joint ranges, its own q7) has {m['n_solutions']} "
        "distinct solutions in range; `ik` is timed for the drawn q's configuration.", "",
        f"Batched, the compiled `ik_all` with each pose its own q7: {m['c_ik_all_small'][0]:.3f} us per "
        f"pose for {m['c_ik_all_small'][1]} poses in one call (median of 200 calls, one thread); "
        f"{m['c_ik_all_batch']:.3f} us per pose for {m['n_batch']} poses in one call (split over "
        f"{m['threads']} threads, which a loaded machine slows). Valid branches per pose (all guards >= 0, "
        f"before joint ranges): {m['valid_per_pose']:.2f} on average; the drawn q among them for "
        f"{100 * m['drawn_found']:.1f} % of the poses; largest |fk(solution) - T| element "
        f"{m['max_err']:.2g}.", "",
        "The issue's goal is all solutions of one pose and one free value in <= 2 us from Python "
        "(IKFast publishes ~4 us per solve) with the guarantees of the 6-joint kernels. The public "
        "entries (rows 2 to 4) do it: the C fast entry (rccl/kinematics/_c/kin_redundant.h) runs "
        "the kernel, moves each joint into its range, evaluates fk of every solution against T "
        "(1e-9), drops duplicates and hands every error or unusual argument to the Python runtime "
        "(rows 5 and 6, numpy), which raises the named errors.", "",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=20000)
    ap.add_argument("--batch", type=int, default=100000)
    ap.add_argument("--out", default=str(ROOT / "reports" / "ik-redundant.md"))
    args = ap.parse_args(argv)
    t0, load0 = time.perf_counter(), os.getloadavg()[0]
    m = measure(args.calls, args.batch)
    text = report(m, time.perf_counter() - t0, (load0, os.getloadavg()[0]))
    Path(args.out).write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
