"""The generated C kernels against Pinocchio's C++, one thread, no Python in the timed loops.

Part of `make bench` (bench/run.py adds its section to reports/bench.md); alone:
``python -m bench.cpp_pinocchio`` prints the section. For every robot whose C kernels are
compiled, it builds bench/cpp/vs_pinocchio.cpp (Pinocchio's algorithms, from the headers
and libraries of the ``pin`` wheel under ``site-packages/cmeel.prefix``) linked with
bench/cpp/kernel_rows.c around the robot's generated ``rccl/kinematics/_c/<robot>.c`` (its
kernels, cut before the CPython runtime), into build/bench/ (untracked; rebuilt when a
source, a flag or the compiler changes), and runs it on the same random configurations for
both sides. The robot's model is Pinocchio's own: its URDF parser (the wheel's compiled
C++, through ``pinocchio.buildModelFromUrdf``) builds it, and :func:`model_text` hands its
joints, link inertias and frames to the program, which rebuilds it with Pinocchio's
``addJoint``/``appendBodyToJoint``/``addFrame`` (including the parser's header would
cost most of the program's compile).

The ``pin`` wheel ships Pinocchio's headers and libraries but not Eigen, which its headers
include: it comes from the cmeel package ``cmeel-eigen`` (the ``bench`` and ``test``
extras of pyproject.toml); without it, CasADi's copy of Eigen 3.4 is used.
"""
from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import subprocess
import sys
import sysconfig
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "bench" / "cpp"
BUILD = ROOT / "build" / "bench"
KERNEL_DIR = ROOT / "rccl" / "kinematics" / "_c"

#: the kernels' flags are those setup.py builds the extension with (its AVX2+FMA and
#: AVX-512F sine and cosine are chosen at run time by CPU, as in the extension)
C_FLAGS = ["-O3", "-fno-math-errno", "-Wno-unused-variable", "-Wno-unused-function"]
#: Pinocchio's side: -O3, no -march=native (see CXX_NOTE), its algorithms instantiated from
#: the headers in this program (not the wheel's precompiled instantiations)
CXX_FLAGS = ["-O3", "-DNDEBUG", "-std=c++17"]


@dataclass(frozen=True)
class Profile:
    """How the comparison program is built, and where it is cached: ``BENCH`` is what make
    bench times; ``CHECK`` only has to compute the same numbers (tests/test_bench_cpp.py), so
    its C++ side is compiled without optimisation and with the wheel's precompiled template
    instantiations (PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION, which the wheel's CMake targets
    set for their users; the program then hands Pinocchio each configuration as the
    Eigen::VectorXd those instantiations take), in a folder of its own: about a third of the
    CPU of the BENCH build. The kernels' side is the same in both (C_FLAGS, the extension's)."""

    name: str
    cxx_flags: tuple[str, ...]
    folder: Path


BENCH = Profile("bench", tuple(CXX_FLAGS), BUILD)
CHECK = Profile("check", ("-O0", "-std=c++17", "-DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION"), BUILD / "check")
#: the compile definitions of the wheel's pinocchio CMake targets (pinocchioTargets.cmake)
PIN_DEFINES = ["-DBOOST_MPL_LIMIT_LIST_SIZE=30", "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30",
               "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS", "-DBOOST_FUSION_INVOKE_MAX_ARITY=12"]
PIN_LIBS = ["-lpinocchio_default"]
CXX_NOTE = ("-march=native is not used on the C++ side: the wheel's libraries are built for "
            "baseline x86-64, and a program built with it (Eigen with AVX) crashed on the Model type "
            "they share (also with -DEIGEN_MAX_ALIGN_BYTES=16)")

#: the goal of issue 16: generated C at least this many times faster per configuration
GOAL = 5.0
#: the computations with that goal (gravity is timed and shown without one)
GOAL_OPS = ("fk", "jacobian6", "jacobian4")
#: issue 27's goals for the dynamics (eq. 4.6): (one configuration per call, batched)
DYNAMICS_GOALS = {"inverse_dynamics": (3.0, 10.0), "inertia_matrix": (3.0, 10.0)}
OPS = ("fk", "jacobian6", "jacobian4", "gravity", "inverse_dynamics", "inertia_matrix")
#: the results file's computations, in its order (Pinocchio's then the kernel's, per configuration)
RESULT_NAMES = ("fk", "jacobian6", "jacobian4", "gravity", "inverse_dynamics", "inertia_matrix")


def result_layout(nj: int) -> tuple[tuple[str, int], ...]:
    """(name, doubles) of the results file of an ``nj``-joint robot: T (16), the two 6 x nj
    Jacobians, gravity and inverse dynamics (nj torques) and the nj x nj inertia matrix."""
    sizes = (16, 6 * nj, 6 * nj, nj, nj, nj * nj)
    return tuple(zip(RESULT_NAMES, sizes))


#: the six-joint arms' layout (the thesis's arms)
RESULT_LAYOUT = result_layout(6)


def goals(op: str) -> tuple[float, float] | None:
    """(one per call, batched) goal of a computation, or None when it has none."""
    if op in GOAL_OPS:
        return GOAL, GOAL
    return DYNAMICS_GOALS.get(op)


class ToolchainError(RuntimeError):
    """A compiler, header or library the comparison needs is missing (the message says which)."""


@dataclass(frozen=True)
class Toolchain:
    """Compilers and the include/library folders of the ``pin`` wheel (cmeel layout)."""

    cc: str
    cxx: str
    prefix: Path            # site-packages/cmeel.prefix
    eigen: Path             # folder holding Eigen/Core
    eigen_source: str       # which package it came from
    python_include: Path    # Python.h: kin_prelude.h includes it (types only)

    def describe(self) -> str:
        return (f"Pinocchio headers and libraries from the `pin` wheel ({self.prefix.parent.name}/{self.prefix.name}), "
                f"Eigen from {self.eigen_source}")


def toolchain() -> Toolchain:
    """Find the compilers and headers; ToolchainError naming exactly what is missing."""
    missing = []
    cc, cxx = shutil.which("gcc") or shutil.which("cc"), shutil.which("g++") or shutil.which("c++")
    if cc is None:
        missing.append("a C compiler (gcc)")
    if cxx is None:
        missing.append("a C++ compiler (g++)")
    prefix = Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix"
    if not (prefix / "include" / "pinocchio" / "algorithm" / "kinematics.hpp").is_file():
        missing.append(f"Pinocchio's headers ({prefix}/include/pinocchio; the `pin` wheel installs them)")
    for lib in PIN_LIBS:
        if not (prefix / "lib" / f"lib{lib[2:]}.so").is_file():
            missing.append(f"{prefix}/lib/lib{lib[2:]}.so (the `pin` wheel's libraries)")
    eigen, source = prefix / "include" / "eigen3", "cmeel-eigen"
    if not (eigen / "Eigen" / "Core").is_file():
        try:
            import casadi
            eigen, source = Path(casadi.__file__).parent / "include" / "eigen3", "CasADi's bundled copy"
        except ImportError:
            pass
    if not (eigen / "Eigen" / "Core").is_file():
        missing.append("Eigen's headers (Eigen/Core: not in the `pin` wheel; pip install cmeel-eigen)")
    pyinc = Path(sysconfig.get_paths()["include"])
    if not (pyinc / "Python.h").is_file():
        missing.append(f"Python.h ({pyinc})")
    if missing:
        raise ToolchainError("bench.cpp_pinocchio: missing " + "; ".join(missing))
    return Toolchain(cc, cxx, prefix, eigen, source, pyinc)


def _compiler_id(exe: str) -> str:
    return subprocess.run([exe, "--version"], capture_output=True, text=True).stdout.splitlines()[0]


def _digest(*parts: object) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(p.read_bytes() if isinstance(p, Path) else str(p).encode())
        h.update(b"\0")
    return h.hexdigest()[:16]


def _compile(cmd: list[str], what: str) -> None:
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise ToolchainError(f"bench.cpp_pinocchio: compiling {what} failed:\n{' '.join(cmd)}\n{r.stderr[-4000:]}")


def kernels_source(robot: str) -> str:
    """The generated C of ``robot`` up to its CPython runtime (kin_runtime.h): prelude, kernels, table."""
    text = (KERNEL_DIR / f"{robot}.c").read_text()
    cut = text.find('#include "kin_runtime.h"')
    if cut < 0:
        raise ToolchainError(f"{KERNEL_DIR / f'{robot}.c'}: no `#include \"kin_runtime.h\"` line to cut at")
    return text[:cut]


def joint_count(robot: str) -> int:
    """The robot's joint count (models/<robot>.toml), which the programs are compiled for."""
    from rcci.models import load_robot
    return int(load_robot(robot).n_joints)


def end_frame(nj: int) -> str:
    """The last link's frame of an ``nj``-joint robot's URDF, where its generated fk and
    Jacobian end (link6 for the thesis's arms, link7 for the Panda)."""
    return f"link{nj}"


def robot_defines(nj: int) -> list[str]:
    """The compile-time constants of an ``nj``-joint robot's programs (both sides)."""
    return [f"-DNJ={nj}", f'-DEND_FRAME="{end_frame(nj)}"']


def build(robot: str, tc: Toolchain | None = None, profile: Profile = BENCH) -> Path:
    """The comparison program of ``robot`` in ``profile.folder``, compiled unless an identical build exists."""
    tc = tc or toolchain()
    out = profile.folder
    out.mkdir(parents=True, exist_ok=True)
    cxx_inc = [f"-I{tc.prefix / 'include'}", f"-I{tc.eigen}", f"-I{SRC}"]
    defines = robot_defines(joint_count(robot))
    # Pinocchio's side depends on the robot only through its joint count: one object per count
    pin_key = _digest(SRC / "vs_pinocchio.cpp", SRC / "kernel_rows.h", list(profile.cxx_flags), PIN_DEFINES, cxx_inc,
                      defines, _compiler_id(tc.cxx), (tc.prefix / "include" / "pinocchio" / "config.hpp"))
    pin_obj = out / f"vs_pinocchio-{pin_key}.o"
    if not pin_obj.exists():
        tmp = pin_obj.with_suffix(f".{os.getpid()}.tmp")
        _compile([tc.cxx, *profile.cxx_flags, *PIN_DEFINES, *defines, *cxx_inc, "-c", str(SRC / "vs_pinocchio.cpp"),
                  "-o", str(tmp)],
                 "bench/cpp/vs_pinocchio.cpp")
        tmp.replace(pin_obj)
    src = kernels_source(robot)
    k_key = _digest(src, *(KERNEL_DIR / h for h in ("kin_prelude.h",)), SRC / "kernel_rows.c", SRC / "kernel_rows.h",
                    C_FLAGS, defines, _compiler_id(tc.cc), str(tc.python_include))
    inc = out / f"{robot}-{k_key}.inc"
    k_obj = out / f"{robot}-kernels-{k_key}.o"
    if not k_obj.exists():
        inc.write_text(src)
        tmp = k_obj.with_suffix(f".{os.getpid()}.tmp")
        _compile([tc.cc, *C_FLAGS, *defines, f"-I{KERNEL_DIR}", f"-I{tc.python_include}", f"-I{SRC}",
                  f'-DRCCL_KERNELS="{inc}"', "-c", str(SRC / "kernel_rows.c"), "-o", str(tmp)],
                 f"the {robot} kernels")
        tmp.replace(k_obj)
    exe = out / f"vs_pinocchio-{robot}-{pin_key}-{k_key}"
    if not exe.exists():
        lib = tc.prefix / "lib"
        tmp = exe.with_suffix(f".{os.getpid()}.tmp")
        _compile([tc.cxx, str(pin_obj), str(k_obj), f"-L{lib}", *PIN_LIBS, f"-Wl,-rpath,{lib}", "-lm", "-o", str(tmp)],
                 f"(linking) the {robot} comparison")
        tmp.replace(exe)
    return exe


def _numbers(values) -> str:
    return " ".join(f"{float(v):.17g}" for v in values)


def model_text(robot: str) -> str:
    """The model of ``models/urdf/<robot>.urdf`` as Pinocchio's URDF parser builds it, in the
    program's model file format (bench/cpp/vs_pinocchio.cpp): per joint its type, axis, parent,
    placement in the parent joint (rotation row-major, then translation, m) and the link
    inertia in the joint frame (mass kg, centre of mass m, rotational inertia kg m^2 about
    it); then the frames link4 and the last link's (link6, the Panda's link7; parent joint,
    placement). Printed with 17 digits:
    the program reads back the same doubles."""
    import pinocchio as pin
    model = pin.buildModelFromUrdf(str(ROOT / "models" / "urdf" / f"{robot}.urdf"))
    lines = []
    for j in range(1, model.njoints):
        joint, y = model.joints[j], model.inertias[j]
        axis = getattr(joint.extract(), "axis", np.zeros(3))
        m = model.jointPlacements[j]
        i = y.inertia
        lines.append(f"joint {model.names[j]} {joint.shortname()} {_numbers(axis)} {model.parents[j]} "
                     f"{_numbers(m.rotation.ravel())} {_numbers(m.translation)} {_numbers([y.mass])} "
                     f"{_numbers(y.lever)} {_numbers([i[0, 0], i[0, 1], i[1, 1], i[0, 2], i[1, 2], i[2, 2]])}")
    for name in ("link4", end_frame(model.nq)):
        if not model.existFrame(name):
            raise ToolchainError(f"models/urdf/{robot}.urdf: no frame {name}")
        f = model.frames[model.getFrameId(name)]
        lines.append(f"frame {name} {f.parentJoint} {_numbers(f.placement.rotation.ravel())} "
                     f"{_numbers(f.placement.translation)}")
    return "\n".join(lines) + "\n"


def gravity_coefficients(robot: str) -> np.ndarray:
    """The generated gravity kernel's coefficients for the model file's link masses and
    centres of mass (those of the URDF inertials), so both sides compute the same torques."""
    from rcci.models import load_robot
    from rccl.kinematics import load
    mod = load(robot)
    model = load_robot(robot)
    masses = np.array([link.mass for link in model.links])
    coms = np.array([link.com for link in model.links])
    return np.array(list(mod.coefficients_from_links(masses, coms).values()), dtype=float)


@dataclass
class Run:
    """One run of the comparison program of one robot."""

    robot: str
    n: int
    repeats: int
    vector_trig: bool
    ns: dict[tuple[str, str], float]          # (computation, "pinocchio" | "c_one" | "c_rows") -> ns/config
    results: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)  # name -> (Pinocchio, kernel)

    def ratio(self, op: str, side: str) -> float:
        return self.ns[(op, "pinocchio")] / self.ns[(op, side)]


def run(robot: str, q: np.ndarray, repeats: int = 5, with_results: bool = False, tc: Toolchain | None = None,
        profile: Profile = BENCH) -> Run:
    """Build (if needed) and run the comparison on configurations ``q`` (N x n for an n-joint
    robot, rad and m); ``profile`` CHECK for agreement only (its timings are not make bench's)."""
    q = np.ascontiguousarray(q, dtype=float)
    nj = joint_count(robot)
    if q.ndim != 2 or q.shape[1] != nj or len(q) == 0:
        raise ValueError(f"bench.cpp_pinocchio.run: q must be N x {nj} ({robot}'s joints) with N >= 1, "
                         f"got shape {q.shape}")
    exe = build(robot, tc, profile)
    tag = f"{robot}-{os.getpid()}"
    qf, cf, rf, mf = (profile.folder / f"{tag}.{x}" for x in ("q.bin", "c.bin", "res.bin", "model.txt"))
    q.tofile(qf)
    gravity_coefficients(robot).tofile(cf)
    mf.write_text(model_text(robot))
    cmd = [str(exe), str(mf), str(qf), str(cf), str(repeats)] + ([str(rf)] if with_results else [])
    try:
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(f"bench.cpp_pinocchio: {' '.join(cmd)} failed ({r.returncode}): {r.stderr.strip()}")
        ns, meta = {}, {}
        for line in r.stdout.splitlines():
            what, who, value = line.split()
            if who == "-":
                meta[what] = value
            else:
                ns[(what, who)] = float(value)
        out = Run(robot, int(meta["configurations"]), repeats, meta["vector_trig"] == "1", ns)
        if with_results:
            layout = result_layout(nj)
            per = sum(2 * k for _, k in layout)
            data = np.fromfile(rf).reshape(len(q), per)
            at = 0
            for name, k in layout:
                out.results[name] = (data[:, at:at + k], data[:, at + k:at + 2 * k])
                at += 2 * k
        return out
    finally:
        for f in (qf, cf, rf, mf):
            f.unlink(missing_ok=True)


def robots() -> list[str]:
    """Every robot under models/ with a URDF and compiled C kernels, of any joint count (the
    programs are compiled per robot for its joint count and last link's frame)."""
    from rcci.models.catalogue import available_robots
    from rccl.kinematics import backend
    return [r for r in available_robots()
            if (ROOT / "models" / "urdf" / f"{r}.urdf").is_file() and (KERNEL_DIR / f"{r}.c").is_file()
            and backend.c_module(r) is not None]


def random_q(robot: str, n: int, rng: np.random.Generator) -> np.ndarray:
    from rccl.kinematics import load
    mod = load(robot)
    lower, upper = np.asarray(mod.LOWER, dtype=float), np.asarray(mod.UPPER, dtype=float)
    return rng.uniform(lower, upper, size=(n, len(lower)))


def measure(n: int = 10000, repeats: int = 25, n_check: int = 500, seed: int = 11) -> tuple[list[Run], Toolchain]:
    """Timings of every robot on ``n`` configurations, and agreement on ``n_check`` of them."""
    tc = toolchain()
    rng = np.random.default_rng(seed)
    runs = []
    for robot in robots():
        timed = run(robot, random_q(robot, n, rng), repeats, tc=tc)
        timed.results = run(robot, random_q(robot, n_check, rng), 1, with_results=True, tc=tc).results
        runs.append(timed)
        print(f"bench: C vs Pinocchio C++, {robot}: "
              + ", ".join(f"{op} {timed.ratio(op, 'c_one'):.3g}x / {timed.ratio(op, 'c_rows'):.3g}x" for op in OPS),
              flush=True)
    return runs, tc


def _ns(t: float) -> str:
    return f"{t:.3g}"


def verdict(r: Run, op: str) -> str:
    """The goal of GOAL_OPS, judged one configuration per call and batched."""
    g = goals(op)
    if g is None:
        return "-"
    one, rows = r.ratio(op, "c_one"), r.ratio(op, "c_rows")
    parts = [f"one per call >= {g[0]:g}x {'met' if one >= g[0] else f'not met ({one:.2g}x)'}",
             f"batched >= {g[1]:g}x {'met' if rows >= g[1] else f'not met ({rows:.2g}x)'}"]
    return "; ".join(parts)


def summary(r: Run) -> str:
    """One robot's ratios for the goals' computations: one configuration per call / batched."""
    def judged(x: float, goal: float) -> str:
        return f"{x:.2g}x ({'met' if x >= goal else 'not met'})"
    return f"{r.robot} " + ", ".join(
        f"{op} {judged(r.ratio(op, 'c_one'), goals(op)[0])} / {judged(r.ratio(op, 'c_rows'), goals(op)[1])}"
        for op in OPS if goals(op) is not None)


def section(runs: list[Run], tc: Toolchain) -> list[str]:
    """The Markdown section of reports/bench.md."""
    if not runs:
        return ["## Generated C vs Pinocchio's C++", "", "No robot has compiled C kernels: nothing measured.", ""]
    n, reps = runs[0].n, runs[0].repeats
    L = ["## Generated C vs Pinocchio's C++ (one thread, no Python)", "",
         "Program: bench/cpp/vs_pinocchio.cpp (Pinocchio) linked with bench/cpp/kernel_rows.c (the robot's generated "
         "`rccl/kinematics/_c/<robot>.c`, its kernels and batched loops as generated, without the CPython runtime), "
         "built by bench/cpp_pinocchio.py into build/bench/ and run once per robot; both sides run on the same "
         f"{n} random configurations (uniform over the joint ranges) in one process; each figure is the best of "
         f"{reps} rounds, a round running every timed pass over them once, in turn (so that both sides see the "
         "same moments of the machine's load), in nanoseconds per configuration.", "",
         f"- {tc.describe()}; the wheel does not ship Eigen, which its headers include.",
         f"- Pinocchio: `{' '.join(['g++', *CXX_FLAGS])}` plus the wheel's CMake compile definitions, algorithms "
         f"instantiated from the headers in the program, linked `{' '.join(PIN_LIBS)}` with an rpath to the wheel's "
         "lib/; the model is the one Pinocchio's URDF parser builds from `models/urdf/<robot>.urdf` "
         "(`pinocchio.buildModelFromUrdf`), its joints, link inertias and frames rebuilt in the program with "
         f"`addJoint`/`appendBodyToJoint`/`addFrame` (bench/cpp_pinocchio.py `model_text`). {CXX_NOTE}.",
         f"- Generated C: `{' '.join(['gcc', *C_FLAGS])}` (setup.py's flags); sines and cosines "
         + ("four at a time with AVX2+FMA (kin_prelude.h; eight at a time with AVX-512F over the blocks of a "
            "batch where the CPU has it), chosen at run time as in the extension."
            if runs[0].vector_trig else "from libm (this CPU lacks AVX2+FMA)."),
         "- `one per call`: the kernel's batched loop called for one configuration at a time (the path of a single "
         "call of the extension, without its argument checks); `batched`: one call over all N configurations (the "
         "extension's loop over rows, one thread; blocks of 32 rows share their sine/cosine and row vector code).",
         "- Each robot's program is compiled for its joint count n (-DNJ=n) and last link's frame linkn "
         "(link6; the Panda's link7, its flange, where its generated fk and Jacobians end: 6 x 7 Jacobians, a 7 x 7 "
         "inertia matrix). Pinocchio's computations: fk = forwardKinematics + updateFramePlacement(linkn) (T6 for six "
         "joints); jacobian6 = computeFrameJacobian(linkn, LOCAL), which is Paul's 6J; jacobian4 = the thesis's "
         "link-4 Jacobian 4J, which Pinocchio has no call for: computeFrameJacobian(linkn, LOCAL), then "
         "updateFramePlacement of link4 and linkn and both 3-row blocks rotated into frame 4's axes; gravity = computeGeneralizedGravity (the generated "
         "gravity kernel with the coefficients of the model file's link masses and centres of mass); "
         "inverse_dynamics = rnea(q, qd, qdd) and inertia_matrix = crba(q) (Pinocchio fills the upper triangle, "
         "the generated kernel all n x n entries), with qd = sin(q + 1), qdd = 2 cos(1.5 q) on both sides.",
         f"- Goal (issue 16): the generated C at least {GOAL:g}x faster per configuration than Pinocchio's C++ "
         "for FK and the Jacobian; issue 27: inverse dynamics and the inertia matrix at least 3x per "
         "configuration and 10x batched.", "",
         "| robot | computation | Pinocchio C++ | C, one per call | C, batched | ratio, one per call | ratio, batched "
         "| goal |",
         "|---|---|---:|---:|---:|---:|---:|---|"]
    for r in runs:
        for op in OPS:
            L.append(f"| {r.robot} | {op} | {_ns(r.ns[(op, 'pinocchio')])} | {_ns(r.ns[(op, 'c_one')])} | "
                     f"{_ns(r.ns[(op, 'c_rows')])} | {r.ratio(op, 'c_one'):.3g}x | {r.ratio(op, 'c_rows'):.3g}x | "
                     f"{verdict(r, op)} |")
    n_check = len(next(iter(runs[0].results.values()))[0]) if runs[0].results else 0
    L += ["", f"Agreement, same program, {n_check} other random configurations per robot (largest element "
          "difference between Pinocchio's C++ and the generated kernel, single-configuration path):", "",
          "| robot | " + " | ".join(RESULT_NAMES) + " |",
          "|---|" + "---:|" * len(RESULT_NAMES)]
    for r in runs:
        L.append(f"| {r.robot} | " + " | ".join(f"{np.abs(a - b).max():.1e}" for a, b in r.results.values()) + " |")
    L.append("")
    return L


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10000, help="configurations timed per robot")
    ap.add_argument("--repeats", type=int, default=25, help="rounds; each figure is the best round")
    ap.add_argument("--out", help="write the section to this Markdown file, headed by the command, the date and "
                                  "the machine's load (default: print it)")
    args = ap.parse_args(argv)
    load0 = os.getloadavg()[0]
    runs, tc = measure(args.n, args.repeats)
    lines = section(runs, tc)
    if args.out:
        import time
        head = ["# Generated C vs Pinocchio's C++: kinematics and dynamics", "",
                f"Generated by `python -m bench.cpp_pinocchio --out {args.out}` (make bench puts the same section "
                f"into reports/bench.md) on {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average "
                f"(1 min) {load0:.2f} at the start, {os.getloadavg()[0]:.2f} at the end, on {os.cpu_count()} cores "
                "(both sides run in turn in one process, so the ratios hold better under load than the absolute "
                "times).", ""]
        Path(args.out).write_text("\n".join(head + lines[1:] if lines[0].startswith("## ") else head + lines) + "\n")
        print(f"wrote {args.out}")
    else:
        print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
