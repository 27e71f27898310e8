"""`make bench`: speed of the generated C, generated Python, CasADi and Pinocchio kinematics, in one run.

Writes reports/bench.md. Every figure is measured in this run on this machine; ratios
are Pinocchio's time divided by the back end's (bigger is faster). Per-call latency is
the best of several timeit repeats of one Python call; batched throughput is one call
over N configurations (C, generated Python's numpy code, CasADi ``map``) against a
Python loop over Pinocchio calls of the same size. Batched C figures are given for fresh
result arrays and for ``out=`` (a preallocated result), next to the memory floor from
this machine's measured bandwidth.
"""
from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import time
import timeit
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import casadi as ca
import numpy as np
import pinocchio as pin

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench import beyond_thesis, cpp_pinocchio  # noqa: E402
from bench.output import progress  # noqa: E402
import rccl.kinematics  # noqa: E402
from rccl.kinematics import backend  # noqa: E402

COMMAND = "make bench  (python -m bench.run)"


# ------------------------------------------------------------------ timing helpers

def per_call(fn: Callable[[], object], budget: float = 0.15) -> float:
    """Seconds per call: best of 5 repeats, each long enough to be measurable."""
    fn()
    n, t = 1, 0.0
    while t < budget / 5:
        n *= 4
        t = timeit.timeit(fn, number=n)
    return min(timeit.repeat(fn, number=n, repeat=5)) / n


def once(fn: Callable[[], object], repeat: int = 1) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def loop(fn: Callable[[np.ndarray], object], rows: np.ndarray) -> float:
    """Seconds for a plain Python loop calling fn on each row."""
    t0 = time.perf_counter()
    for r in rows:
        fn(r)
    return time.perf_counter() - t0


# ------------------------------------------------------------------ the four back ends

@dataclass
class Op:
    """One computation measured on every back end."""

    name: str
    c: Callable            # single call, args per configuration
    py: Callable           # generated Python, one configuration
    py_many: Callable      # generated Python, batched numpy code
    cas: ca.Function | None
    pin: Callable          # Pinocchio, one configuration
    make_args: Callable[[np.ndarray], tuple]  # Q (N, 6) -> batched args
    public: Callable       # the public API call (takes out=)
    results: dict = field(default_factory=dict)


def pin_model(robot: str):
    model = pin.buildModelFromUrdf(str(ROOT / "models" / "urdf" / f"{robot}.urdf"))
    data = model.createData()
    return model, data, model.getFrameId("link6")


def build_ops(robot: str, rng: np.random.Generator) -> tuple[list[Op], object]:
    mod = rccl.kinematics.load(robot)
    cm = backend.c_module(robot)
    if cm is None:
        raise SystemExit("bench: the C kernels are not compiled; run `pip install -e .` first")
    model, data, fid = pin_model(robot)
    cas = {}
    for name in ("fk", "jacobian6", "cartesian_from_joint6", "torque_from_force6", "joint_from_cartesian6",
                 "force_from_torque6", "gravity", "ik", "ik_all"):
        cas[name] = ca.Function.load(str(ROOT / "rccl" / "kinematics" / "casadi" / robot / f"{name}.casadi"))
    coeffs = np.array([0.5] * len(mod.GRAVITY_COEFFS))  # timing only; values do not matter

    def pin_fk(q):
        pin.forwardKinematics(model, data, q)
        return pin.updateFramePlacement(model, data, fid).homogeneous

    def pin_j6(q):
        return pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)

    def v6(n):
        return rng.normal(size=(n, 6))

    ops = [
        Op("fk", cm.fk, mod._fk_one, mod._fk_many, cas["fk"], pin_fk, lambda Q: (Q,), mod.fk),
        Op("jacobian6", cm.jacobian6, mod._jacobian6_one, mod._jacobian6_many, cas["jacobian6"], pin_j6,
           lambda Q: (Q,), mod.jacobian6),
        Op("cartesian_from_joint6", cm.cartesian_from_joint6, mod._cartesian_from_joint6_one,
           mod._cartesian_from_joint6_many, cas["cartesian_from_joint6"],
           lambda q, dq: pin_j6(q) @ dq, lambda Q: (Q, v6(len(Q))),
           lambda q, x, out=None: mod.cartesian_from_joint(q, x, 6, out=out)),
        Op("torque_from_force6", cm.torque_from_force6, mod._torque_from_force6_one,
           mod._torque_from_force6_many, cas["torque_from_force6"],
           lambda q, f: pin_j6(q).T @ f, lambda Q: (Q, v6(len(Q))),
           lambda q, x, out=None: mod.torque_from_force(q, x, 6, out=out)),
        Op("joint_from_cartesian6", cm.joint_from_cartesian6, mod._joint_from_cartesian6_one,
           mod._joint_from_cartesian6_many, cas["joint_from_cartesian6"],
           lambda q, dc: np.linalg.solve(pin_j6(q), dc), lambda Q: (Q, v6(len(Q))),
           lambda q, x, out=None: mod.joint_from_cartesian(q, x, 6, out=out)),
        Op("force_from_torque6", cm.force_from_torque6, mod._force_from_torque6_one,
           mod._force_from_torque6_many, cas["force_from_torque6"],
           lambda q, tau: np.linalg.solve(pin_j6(q).T, tau), lambda Q: (Q, v6(len(Q))),
           lambda q, x, out=None: mod.force_from_torque(q, x, 6, out=out)),
        Op("gravity", cm.gravity, mod._gravity_one, mod._gravity_many, cas["gravity"],
           lambda q, c: pin.computeGeneralizedGravity(model, data, q),
           lambda Q: (Q, np.broadcast_to(coeffs, (len(Q), len(coeffs))).copy()), mod.gravity),
    ]
    return ops, (mod, cm, model, data, fid, cas)


def random_q(mod, n: int, rng: np.random.Generator) -> np.ndarray:
    """Configurations inside the joint ranges, away from the singular boundaries."""
    lo, hi = np.asarray(mod.LOWER), np.asarray(mod.UPPER)
    q = rng.uniform(lo, hi, size=(n, 6))
    return q


#: calls timed per public batched figure, the best kept: a 1e5-row call lasts about a
#: millisecond over two threads, and one descheduling of either thread (the other core
#: taken by the kernel or a Python thread for a moment) costs a large part of it; with 3
#: calls two runs of this bench gave 11.7 and 17.1 ns for the same row
PUBLIC_REPEATS = 7


def measure_op(op: Op, Q1: np.ndarray, big: dict[int, np.ndarray], n_pin_loop: dict[int, int]) -> None:
    args1 = op.make_args(Q1[:1])
    one = tuple(a[0] for a in args1)
    cas_one = [np.asarray(a, dtype=float) for a in one]
    r = op.results
    r["c_call"] = per_call(lambda: op.c(*one))
    r["py_call"] = per_call(lambda: op.py(*one))
    r["cas_call"] = per_call(lambda: op.cas(*cas_one))
    r["pin_call"] = per_call(lambda: op.pin(*one))
    for n, Q in big.items():
        args = op.make_args(Q)
        r[f"c_{n}"] = once(lambda: op.c(*args), repeat=3) / n
        # the public call as users make it: a fresh result each call, and with out=
        r[f"pub_{n}"] = once(lambda: op.public(*args), repeat=PUBLIC_REPEATS) / n
        out = op.public(*args)
        r[f"out_{n}"] = once(lambda: op.public(*args, out=out), repeat=PUBLIC_REPEATS) / n
        r["bytes"] = (sum(np.asarray(a).nbytes for a in args) + out.nbytes) / n
        del out
        r[f"py_{n}"] = once(lambda: op.py_many(*args)) / n
        fmap = op.cas.map(n)
        cargs = [np.ascontiguousarray(a.reshape(n, -1).T) for a in args]
        r[f"cas_{n}"] = once(lambda: fmap(*cargs)) / n
        m = n_pin_loop[n]
        rows = list(zip(*[a[:m] for a in args]))
        t0 = time.perf_counter()
        for row in rows:
            op.pin(*row)
        r[f"pin_{n}"] = (time.perf_counter() - t0) / m


def bandwidth(nbytes: int = 400_000_000) -> dict[str, float]:
    """This machine's memory bandwidth (bytes/s): copy between warm arrays (bytes read +
    written), writes to warm memory, and writes to freshly allocated memory (first touch:
    page faults included), each the best of 3."""
    n = nbytes // 8
    src, dst = np.ones(n), np.zeros(n)
    copy = once(lambda: np.copyto(dst, src), repeat=3)
    warm = once(lambda: dst.fill(2.0), repeat=3)
    del dst

    def fresh():
        a = np.empty(n)
        a.fill(3.0)
    first = once(fresh, repeat=3)
    return {"copy": 2 * nbytes / copy, "write": nbytes / warm, "first_touch": nbytes / first}


# ------------------------------------------------------------------ inverse kinematics

def dls_ik(model, data, fid, target: pin.SE3, q0: np.ndarray, tol: float = 1e-10,
           max_iter: int = 200, damping: float = 1e-6) -> tuple[np.ndarray, int, bool]:
    """Damped least squares on Pinocchio: q <- q + J^T (J J^T + lambda I)^-1 e, e = log6 error in frame 6."""
    q = q0.copy()
    for it in range(max_iter):
        pin.forwardKinematics(model, data, q)
        current = pin.updateFramePlacement(model, data, fid)
        err = pin.log6(current.actInv(target)).vector
        if np.linalg.norm(err) < tol:
            return q, it, True
        j = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)
        j = pin.Jlog6(current.actInv(target)) @ j
        q = q + j.T @ np.linalg.solve(j @ j.T + damping * np.eye(6), err)
    return q, max_iter, False


def pose_error(t_a: np.ndarray, t_b: np.ndarray) -> tuple[float, float]:
    """(position error m, rotation error rad) between two homogeneous transforms."""
    dp = np.linalg.norm(t_a[:3, 3] - t_b[:3, 3])
    # the angle of the relative rotation via log3 (arccos of the trace loses half the digits)
    ang = np.linalg.norm(pin.log3(t_a[:3, :3].T @ t_b[:3, :3]))
    return float(dp), float(ang)


def measure_ik(mod, cm, model, data, fid, cas, Q: np.ndarray, big: dict[int, np.ndarray], rng) -> dict:
    out: dict = {}
    T = cm.fk(Q)[0]
    signs = np.array(mod.Config().signs, dtype=float)   # every sign +1
    cfg = signs if len(signs) > 1 else signs[0]        # the kernel's config: signs, or one sign (a scalar)
    out["n_configs"] = len(mod.Config.all())
    t1 = T[0]
    out["c_ik_call"] = per_call(lambda: cm.ik(t1, cfg))
    out["py_ik_call"] = per_call(lambda: mod._ik_one(t1, cfg))
    out["cas_ik_call"] = per_call(lambda: cas["ik"](t1, cfg))
    out["c_ik_all_call"] = per_call(lambda: cm.ik_all(t1))
    config = mod.Config()  # made once: building a Config (a dataclass) costs more than ik
    out["public_ik_call"] = per_call(lambda: mod.ik(t1, config))
    out["public_ik_all_call"] = per_call(lambda: mod.ik_all(t1))
    q1 = Q[0]
    t_q1 = cm.fk(q1)[0]
    cfg1 = mod.config_of(q1)
    out["public_ik_ref_call"] = per_call(lambda: mod.ik(t_q1, cfg1, q_ref=q1))
    out["public_config_of_call"] = per_call(lambda: mod.config_of(q1))
    Tp = cm.fk(Q[:1000])[0]
    out["public_ik_all_1000"] = once(lambda: mod.ik_all(Tp), repeat=2) / 1000
    for n, Qb in big.items():
        Tb = cm.fk(Qb)[0]
        cfgs = np.broadcast_to(cfg, (n,) + np.shape(cfg)).copy()
        out[f"c_ik_{n}"] = once(lambda: cm.ik(Tb, cfgs), repeat=2) / n
        out[f"c_ik_all_{n}"] = once(lambda: cm.ik_all(Tb), repeat=2) / n
        out[f"py_ik_{n}"] = once(lambda: mod._ik_many(Tb, cfgs)) / n
    # accuracy of the closed form: every valid solution reproduces its pose
    n_acc = 2000
    Ta = T[:n_acc]
    qs, guards = cm.ik_all(Ta)
    valid = (guards >= 0).all(axis=2)
    back = cm.fk(qs.reshape(-1, 6))[0].reshape(n_acc, -1, 4, 4)
    err = np.abs(back - Ta[:, None])[valid]
    out["c_ik_all_valid"] = float(valid.sum(axis=1).mean())
    out["c_ik_all_maxerr"] = float(err.max())
    # numerical: damped least squares on Pinocchio from a start 0.3 rad (uniform, per joint) off the answer
    n_num = 200
    t_num = 0.0
    iters, ok, pos_err, rot_err = [], 0, [], []
    for i in range(n_num):
        target = pin.SE3(T[i])
        q0 = Q[i] + rng.uniform(-0.3, 0.3, 6)
        t0 = time.perf_counter()
        q, it, conv = dls_ik(model, data, fid, target, q0)
        t_num += time.perf_counter() - t0
        iters.append(it)
        ok += conv
        pin.forwardKinematics(model, data, q)
        e = pose_error(pin.updateFramePlacement(model, data, fid).homogeneous, T[i])
        pos_err.append(e[0])
        rot_err.append(e[1])
    out.update(dls_time=t_num / n_num, dls_ok=ok / n_num, dls_iters=float(np.mean(iters)),
               dls_pos=float(np.max(pos_err)), dls_rot=float(np.max(rot_err)), dls_n=n_num)
    # same poses through the closed form for the per-pose accuracy comparison
    pe, re = [], []
    for i in range(n_num):
        q = mod.ik(T[i], mod.config_of(Q[i]))
        e = pose_error(cm.fk(q)[0], T[i])
        pe.append(e[0])
        re.append(e[1])
    out.update(cf_pos=float(np.max(pe)), cf_rot=float(np.max(re)))
    return out


# ------------------------------------------------------------------ report

def machine() -> list[str]:
    cpu = platform.processor() or "?"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        gcc = subprocess.run(["gcc", "--version"], capture_output=True, text=True).stdout.splitlines()[0]
    except OSError:
        gcc = "no gcc"
    return [
        f"- machine: {cpu}, {os.cpu_count()} logical cores, {platform.system()} {platform.release()}",
        f"- Python {platform.python_version()}, numpy {np.__version__}, Pinocchio {pin.__version__}, "
        f"CasADi {ca.__version__}, compiler: {gcc} (flags -O3 -fno-math-errno, from setup.py; numpy C API for the "
        f"public fast entry; batched and single-row sin/cos four at a time with AVX2+FMA (kin_prelude.h) when the CPU has them, eight at a time with AVX-512F over the blocks of a batch where it has that too (same bits); "
        f"results that are polynomials in sines and cosines are not rescanned for NaN/inf)",
    ]


def us(t: float) -> str:
    return f"{t * 1e6:.3g}"


def ns(t: float) -> str:
    return f"{t * 1e9:.3g}"


def ratio(a: float, b: float) -> str:
    return f"{a / b:.3g}x"


#: issue 16's goal for the batched public call: within this factor of the memory floor
FLOOR_GOAL = 2.0


def floor_summary(robot: str, ops: list[Op], sizes: list[int], bw: dict[str, float]) -> list[str]:
    """The batched public call against the memory floor: the worst computation per N, with
    out= and with a fresh result, and the goal (<= FLOOR_GOAL times the floor)."""
    L = []
    for n in sizes:
        worst = {}
        for key in ("out", "pub"):
            rat = {op.name: op.results[f"{key}_{n}"] / (op.results["bytes"] / bw["copy"]) for op in ops}
            name = max(rat, key=rat.get)
            worst[key] = (name, rat[name])
        (no, ro), (nf, rf) = worst["out"], worst["pub"]
        verdict = "met" if ro <= FLOOR_GOAL else f"not met: {ro / FLOOR_GOAL:.2f}x over the goal"
        L.append(f"- {robot}, N = {n:.0e}: public call with `out=` at most {ro:.2f}x the memory floor ({no}; goal <= "
                 f"{FLOOR_GOAL:g}x: {verdict}); with a fresh result at most {rf:.2f}x ({nf}"
                 + ("" if rf <= FLOOR_GOAL else f", {rf / FLOOR_GOAL:.2f}x over the goal: the page faults of new memory")
                 + ").")
    return L


@dataclass
class RobotBench:
    """The measurements of one robot: per computation (ops), the public calls, inverse kinematics."""

    robot: str
    ops: list[Op]
    public: dict[str, tuple[float, float]]   # call -> (seconds, Pinocchio's seconds)
    ik: dict


def write_report(path: Path, benches: list[RobotBench], sizes: list[int], n_pin: dict[int, int],
                 shared: dict, elapsed: float, cpp: list[str] | None = None) -> None:
    robots = ", ".join(b.robot for b in benches)
    bw = shared["_bandwidth"]
    L = ["# Kinematics benchmark: generated C, generated Python, CasADi, Pinocchio", "",
         f"Command: `{COMMAND}` (bench/run.py); robots: {robots}; measured {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} "
         f"in one run of {elapsed:.0f} s; load average (1 min) {shared['_load'][0]:.2f} at the start, "
         f"{shared['_load'][1]:.2f} at the end (2 cores: figures are trustworthy when it stays below 1).", ""]
    L += machine()
    L += ["", "Summary of the goals of issue 16 (details in the sections below):", ""]
    if "_cpp" in shared:
        runs = shared["_cpp"]
        L += [f"- generated C vs Pinocchio's C++, one thread, one configuration per call / batched (goal >= "
              f"{cpp_pinocchio.GOAL:g}x for FK and the Jacobian, issue 27: >= 3x / 10x for inverse dynamics and "
              "the inertia matrix): "
              + "; ".join(cpp_pinocchio.summary(r) for r in runs) + "."]
    for b in benches:
        L += floor_summary(b.robot, b.ops, sizes, bw)
    L += ["",
          "Ratios are Pinocchio's time over the back end's (bigger is faster). `C` is the compiled",
          "kernel called directly (`rccl.kinematics._c.<robot>.<kernel>`, which checks shapes and NaN",
          "itself); `Python` the generated straight-line code (`_<kernel>_one` / `_<kernel>_many`);",
          "`CasADi` the saved SX Function (`casadi.Function.load`), batched with `Function.map`;",
          "Pinocchio the equivalent call on `models/urdf/<robot>.urdf`: FK = forwardKinematics +",
          "updateFramePlacement; Jacobian = computeFrameJacobian(LOCAL); the four Jacobian",
          "computations = that Jacobian times, transposed times, or solved against the vector;",
          "gravity = computeGeneralizedGravity.", "",
          "Through the public API (`rccl.kinematics.<robot>.fk(q)` etc.): float64 numpy arrays (one",
          "configuration or a batch), gravity coefficients as an array or a mapping of floats or of",
          "`Value` records, poses and Configs for `ik`/`ik_all`/`config_of` take the C fast entry",
          "(shape, NaN, pose, guard and result checks in C); anything else (lists, other dtypes,",
          "failing checks) goes through the Python checks of `rccl/kinematics/runtime.py`, which",
          "build the error messages. Frame 6 for the Jacobian computations.", "",
          f"Batched throughput: memory bandwidth of this machine, measured in this run (400 MB arrays, best of 3): copy "
          f"{bw['copy'] / 1e9:.1f} GB/s (read + written), writes to warm memory {bw['write'] / 1e9:.1f} GB/s, "
          f"writes to freshly allocated memory {bw['first_touch'] / 1e9:.2f} GB/s (first touch: the page faults "
          "of new memory; measured at the end of the run, on pages the VM has backed before; memory the VM has not "
          "touched yet is far slower, so the first large results of a run, e.g. the first `C kernel` row, can cost "
          "several times more than the kernel). The memory floor of a row is its bytes (inputs read + result written) at the copy "
          f"bandwidth. Threads: large batches are split over {shared['_threads']} thread(s) "
          "(`RCCL_KINEMATICS_THREADS`, default the online CPUs).", "",
          "Columns: `C kernel` the bare kernel (`_c.<robot>.<kernel>`, fresh results); `public` the public call "
          "(`rccl.kinematics.<robot>.fk(Q)` etc., checks of inputs, guards and results in C) with a fresh result, "
          f"and with `out=` a preallocated one; each the best of {PUBLIC_REPEATS} calls (`out=`: of {2 * PUBLIC_REPEATS}, "
          f"{PUBLIC_REPEATS} of them timed in rounds over every computation, so that a second-long disturbance of "
          "the machine cannot spoil all of one computation's calls). The target is judged on the public call "
          "with `out=`: it is the steady state of a program that computes batches repeatedly (the result buffer "
          "is reused), while the fresh figure also measures how fast this VM maps new pages, which no kernel "
          "can change; its ratio is given beside it.", ""]
    for b in benches:
        L += robot_section(b, sizes, n_pin, bw)
    L += cpp or []
    path.write_text("\n".join(L) + "\n")


def robot_section(b: RobotBench, sizes: list[int], n_pin: dict[int, int], bw: dict[str, float]) -> list[str]:
    """One robot's tables: single calls, public calls, batched throughput, inverse kinematics."""
    ops, ik = b.ops, b.ik
    L = [f"## {b.robot}", "",
         f"### {b.robot}: one call from Python (latency, microseconds)", "",
         "| computation | C | Python | CasADi | Pinocchio | C vs Pinocchio | target >= 3x |",
         "|---|---:|---:|---:|---:|---:|---|"]
    for op in ops:
        r = op.results
        sp_ = r["pin_call"] / r["c_call"]
        L.append(f"| {op.name} | {us(r['c_call'])} | {us(r['py_call'])} | {us(r['cas_call'])} | {us(r['pin_call'])} | "
                 f"{sp_:.3g}x | {'reached' if sp_ >= 3 else f'missed ({sp_:.2g}x)'} |")
    L += ["", f"### {b.robot}: through the public API (microseconds)", "",
          "| call | microseconds | Pinocchio | vs Pinocchio | target >= 3x |", "|---|---:|---:|---:|---|"]
    for name, val in b.public.items():
        t, tp = val
        sp_ = tp / t
        L.append(f"| {name} | {us(t)} | {us(tp)} | {ratio(tp, t)} | {'reached' if sp_ >= 3 else f'missed ({sp_:.2g}x)'} |")
    for n in sizes:
        L += ["", f"### {b.robot}: batched, N = {n:.0e} (nanoseconds per configuration)", "",
              f"Pinocchio: a Python loop over {n_pin[n]:.0e} configurations.", "",
              "| computation | C kernel | public | public, out= | memory floor | Python (numpy) | CasADi map | "
              "Pinocchio loop | out= vs Pinocchio | fresh vs Pinocchio | target >= 50x (out=) |",
              "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
        for op in ops:
            r = op.results
            sp_ = r[f"pin_{n}"] / r[f"out_{n}"]
            floor = r["bytes"] / bw["copy"]
            L.append(f"| {op.name} | {ns(r[f'c_{n}'])} | {ns(r[f'pub_{n}'])} | {ns(r[f'out_{n}'])} | {ns(floor)} | "
                     f"{ns(r[f'py_{n}'])} | {ns(r[f'cas_{n}'])} | {ns(r[f'pin_{n}'])} | {sp_:.3g}x | "
                     f"{r[f'pin_{n}'] / r[f'pub_{n}']:.3g}x | {'reached' if sp_ >= 50 else f'missed ({sp_:.3g}x)'} |")
    L += ["", f"### {b.robot}: inverse kinematics", "",
          f"Closed form (thesis 3.19-3.53), one configuration (`ik`) and all {ik['n_configs']} (`ik_all`, one",
          "kernel with subexpressions shared between configurations):", "",
          "| | C | Python | CasADi |", "|---|---:|---:|---:|",
          f"| one call, one configuration (us) | {us(ik['c_ik_call'])} | {us(ik['py_ik_call'])} | {us(ik['cas_ik_call'])} |",
          f"| one call, all {ik['n_configs']} configurations (us) | {us(ik['c_ik_all_call'])} | | |",
          f"| public `ik(T, config)` / `ik_all(T)` (us) | {us(ik['public_ik_call'])} / {us(ik['public_ik_all_call'])} | | |",
          f"| public `ik(T, config, q_ref=q)` / `config_of(q)` (us) | {us(ik['public_ik_ref_call'])} / {us(ik['public_config_of_call'])} | | |",
          f"| public `ik_all(T)` on a batch of 1000 poses (us per pose; checks, deduplication and the lists built in C) | {us(ik['public_ik_all_1000'])} | | |"]
    for n in sizes:
        t8 = ik[f"c_ik_all_{n}"]
        L.append(f"| batched N = {n:.0e}: one configuration (ns/pose) | {ns(ik[f'c_ik_{n}'])} | {ns(ik[f'py_ik_{n}'])} | |")
        L.append(f"| batched N = {n:.0e}: all {ik['n_configs']} configurations (ns/pose; target <= 1000) | {ns(t8)} "
                 f"({'reached' if t8 <= 1e-6 else f'missed by {t8 / 1e-6:.2f}x'}) | | |")
    L += ["",
          f"Accuracy of the closed form: over 2000 random poses, {ik['c_ik_all_valid']:.2f} valid solutions per pose on "
          f"average (guards >= 0), and FK of every valid solution reproduces the pose to {ik['c_ik_all_maxerr']:.1e} "
          "(largest element difference).", "",
          f"Numerical comparison on {ik['dls_n']} of the same poses: damped least squares on Pinocchio",
          "(log6 error in frame 6, Jlog6-corrected frame Jacobian, damping 1e-6, tolerance 1e-10, at most",
          "200 iterations), started 0.3 rad (uniform per joint) from the true joints. The closed form",
          "uses the public `ik(T, config_of(q_true))`.", "",
          "| solver | time per pose (us) | converged | mean iterations | max position error (m) | max rotation error (rad) |",
          "|---|---:|---:|---:|---:|---:|",
          f"| DLS on Pinocchio | {us(ik['dls_time'])} | {ik['dls_ok'] * 100:.0f}% | {ik['dls_iters']:.1f} | "
          f"{ik['dls_pos']:.1e} | {ik['dls_rot']:.1e} |",
          f"| closed form, C kernel, one configuration (time of the bare kernel call) | {us(ik['c_ik_call'])} | 100% | - | {ik['cf_pos']:.1e} | {ik['cf_rot']:.1e} |",
          f"| closed form, C kernel, all {ik['n_configs']} (batched) | {us(ik[f'c_ik_all_{sizes[0]}'])} | | | | |",
          ""]
    return L


def retime_out_in_rounds(ops: list[Op], big: dict[int, np.ndarray], rounds: int = PUBLIC_REPEATS) -> None:
    """The public ``out=`` figures timed again, in rounds over every computation, keeping the
    best of both passes: a disturbance of the machine lasting a second or so (another
    process, this VM's memory scanner) then spoils one call of each computation instead of
    every call of one (the first pass times a computation's calls back to back)."""
    for n, Q in big.items():
        calls = []
        for op in ops:
            args = op.make_args(Q)
            calls.append((op, args, op.public(*args)))
        for _ in range(rounds):
            for op, args, out in calls:
                t0 = time.perf_counter()
                op.public(*args, out=out)
                op.results[f"out_{n}"] = min(op.results[f"out_{n}"], (time.perf_counter() - t0) / n)
        del calls


def measure_robot(robot: str, sizes: list[int], n_pin: dict[int, int], rng: np.random.Generator) -> RobotBench:
    """Every table's measurements for one robot."""
    ops, (mod, cm, model, data, fid, cas) = build_ops(robot, rng)
    big = {n: random_q(mod, n, rng) for n in sizes}
    Q1 = random_q(mod, 10, rng)
    for op in progress(ops, f"kinematics {robot}"):
        t0 = time.perf_counter()
        measure_op(op, Q1, big, n_pin)
        print(f"bench: {robot}: {op.name}: {time.perf_counter() - t0:.1f} s", flush=True)
    retime_out_in_rounds(ops, big)
    q = Q1[0]
    pin = {op.name: op.results["pin_call"] for op in ops}
    c_vec = np.array([0.5] * len(mod.GRAVITY_COEFFS))
    c_map = dict(zip(mod.GRAVITY_COEFFS, c_vec))
    from rcci.models import load_robot
    model_coeffs = load_robot(robot).gravity_coeffs  # what rccl.adaptive passes
    v = np.linspace(0.1, 0.6, 6)
    public = {
        "fk(q)": (per_call(lambda: mod.fk(q)), pin["fk"]),
        "jacobian6(q)": (per_call(lambda: mod.jacobian6(q)), pin["jacobian6"]),
        "cartesian_from_joint(q, dq)": (per_call(lambda: mod.cartesian_from_joint(q, v)), pin["cartesian_from_joint6"]),
        "torque_from_force(q, f)": (per_call(lambda: mod.torque_from_force(q, v)), pin["torque_from_force6"]),
        "joint_from_cartesian(q, dc)": (per_call(lambda: mod.joint_from_cartesian(q, v)), pin["joint_from_cartesian6"]),
        "force_from_torque(q, tau)": (per_call(lambda: mod.force_from_torque(q, v)), pin["force_from_torque6"]),
        "gravity(q, c), c an array": (per_call(lambda: mod.gravity(q, c_vec)), pin["gravity"]),
        "gravity(q, coeffs), coeffs a dict of floats": (per_call(lambda: mod.gravity(q, c_map)), pin["gravity"]),
        "gravity(q, model.gravity_coeffs), the loaded model's mapping of Values": (
            per_call(lambda: mod.gravity(q, model_coeffs)), pin["gravity"]),
    }
    ik = measure_ik(mod, cm, model, data, fid, cas, random_q(mod, 5000, rng), big, rng)
    print(f"bench: {robot}: ik: done", flush=True)
    return RobotBench(robot, ops, public, ik)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", action="append",
                    help="a robot to measure (repeatable); default every robot with compiled C kernels")
    ap.add_argument("--sizes", default="100000,1000000")
    ap.add_argument("--out", default=str(ROOT / "reports" / "bench.md"))
    ap.add_argument("--no-cpp", action="store_true",
                    help="leave out the C++ comparison with Pinocchio (bench/cpp_pinocchio.py)")
    ap.add_argument("--no-beyond", action="store_true",
                    help="leave out the redundant IK and collision sections (bench/beyond_thesis.py)")
    args = ap.parse_args(argv)
    # the per-arm kinematics sections (measure_robot: link6, six joint variables) keep to the six-joint
    # arms; the C++ comparison below (cpp_pinocchio.measure) covers every arm, the Panda included
    robots = args.robot or [r for r in cpp_pinocchio.robots() if cpp_pinocchio.joint_count(r) == 6]
    if not robots:
        raise SystemExit("bench: no robot has compiled C kernels; run `pip install -e .` first")
    t_start = time.perf_counter()
    load_start = os.getloadavg()[0]
    rng = np.random.default_rng(7)
    sizes = [int(s) for s in args.sizes.split(",")]
    # the Pinocchio loop runs the full N (the brief asks for it); it dominates the run time
    n_pin = {n: n for n in sizes}
    benches = [measure_robot(robot, sizes, n_pin, rng) for robot in robots]
    shared: dict = {"_bandwidth": bandwidth(), "_threads": backend.c_module(robots[0]).threads()}
    cpp: list[str] = []
    if not args.no_cpp:
        # every robot with compiled kernels, not only --robot: a C++ program per robot, a few seconds each
        runs, tc = cpp_pinocchio.measure()
        shared["_cpp"] = runs
        cpp = cpp_pinocchio.section(runs, tc)
    if not args.no_beyond:
        cpp = cpp + beyond_thesis.sections()
    shared["_load"] = (load_start, os.getloadavg()[0])
    write_report(Path(args.out), benches, sizes, n_pin, shared, time.perf_counter() - t_start, cpp)
    print(f"bench: wrote {args.out} in {time.perf_counter() - t_start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
