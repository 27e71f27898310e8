"""A hidden truth for an arm: a simula parameter file drawn away from the robot data file.

Calibration is only shown to work when it finds values it was not given. ``hidden_truth``
draws, for a seed, a parameter file (schema of docs/simula.md) whose torque sensitivities
and friction are each 10-30 % away from the data file (up or down at random), whose
gravity coefficients are 3-10 % away, and whose DH table has errors of Table 3.1's size
(0.1-0.5 mm, 0.05-0.25 deg) with random signs. ``calib hidden-truth`` writes one; a test or
a user then records against it (``calib record ... --simula "--params FILE --seed N"``)
and scores the fits against it in ``calib report``.

With ``inertials`` (``calib hidden-truth --inertials``) the file also moves what the dynamics
identification fits: each link's mass by 5-15 % and its rotational inertia about the centre
of mass by 10-30 % more, and each motor's rotor inertia by 10-30 % (``[inertials]``
mass_scale, inertia_scale, rotor_scale: rci.simula.params), drawn from a generator of their own so that the other tables are
those of the same seed without it.
"""
from __future__ import annotations

import numpy as np

from rcci.calib.params import dumps
from rcci.models import load_robot
from rcci.models.params import SCHEMA

FACTOR_RANGE = (0.10, 0.30)        # relative distance of sigma and friction from the data file
GRAVITY_RANGE = (0.03, 0.10)       # ... of the gravity coefficients (their centres of mass move)
DEG = np.pi / 180


def _factors(rng: np.random.Generator, n: int, span: tuple[float, float]) -> np.ndarray:
    """``n`` factors 1 +- u, u uniform in ``span``, the sign at random."""
    return 1.0 + rng.choice((-1.0, 1.0), n) * rng.uniform(*span, n)


MASS_RANGE = (0.05, 0.15)          # relative distance of the link masses (--inertials)
INERTIA_RANGE = (0.10, 0.30)       # ... of their rotational inertias and of the rotors'
HOLD_SHARE = 0.8   # a valid truth holds the arm still anywhere in its ranges under this share of max_current


def hidden_inertials(robot: str, seed: int) -> dict:
    """The ``[inertials]`` table of the module docstring for ``seed``."""
    rng = np.random.default_rng([seed, 27])
    n = load_robot(robot).n_joints
    mass = _factors(rng, n, MASS_RANGE)
    inertia = _factors(rng, n, INERTIA_RANGE)
    rotor = _factors(rng, n, INERTIA_RANGE)
    return {"inertials": {"mass_scale": [float(x) for x in np.round(mass, 4)],
                          "inertia_scale": [float(x) for x in np.round(inertia, 4)],
                          "rotor_scale": [float(x) for x in np.round(rotor, 4)]}}


def hidden_truth(robot: str, seed: int) -> dict:
    """The parameter file's tables (``rcci.calib.params.dumps`` writes them) of a truth of ``robot``
    drawn with ``seed`` as the module docstring says, redrawn (from the same generator) until
    it is an arm that could exist: one whose motors hold it against gravity and move it against
    Coulomb friction anywhere in its ranges under HOLD_SHARE of their current limit (a real
    motor too weak for its arm would not have been built). Joints with a zero data-file value
    (no friction given) stay zero."""
    rng = np.random.default_rng(seed)
    for _ in range(200):
        data = _draw(robot, seed, rng)
        if _holds(robot, data):
            return data
    raise ValueError(f"robot {robot}: no valid hidden truth in 200 draws of seed {seed}")


def _holds(robot: str, data: dict) -> bool:
    """True when the truth ``data`` moves its arm at every one of 400 random poses under
    HOLD_SHARE of each motor's current limit (gravity plus Coulomb friction, through G)."""
    from rcci.calib.robot import robot_info

    info = robot_info(robot)
    m = load_robot(robot)
    coeffs = np.array([data["gravity_coeffs"].get(k, m.gravity_coeffs[k].value) for k in info.gravity_names])
    fc = np.maximum(data["friction"]["coulomb_pos"], data["friction"]["coulomb_neg"])
    q = np.random.default_rng(0).uniform(info.lower, info.upper, (400, len(info.lower)))
    tau = np.abs(np.array([info.regressor(x) @ coeffs for x in q])) + fc
    Ginv_T = np.abs(np.linalg.inv(np.asarray(info.drive.G, float).T))
    cur = (tau @ Ginv_T.T) / np.asarray(data["motors"]["torque_sensitivity"])
    return bool((cur <= HOLD_SHARE * np.asarray(m.max_current, float)).all())


def _draw(robot: str, seed: int, rng: np.random.Generator) -> dict:
    m = load_robot(robot)
    n = m.n_joints
    sigma = np.asarray(m.motors.torque_sensitivity.values, float) * _factors(rng, n, FACTOR_RANGE)
    fr = m.friction
    friction = {}
    for key in ("coulomb_pos", "coulomb_neg", "viscous_pos", "viscous_neg", "static_pos", "static_neg"):
        base = np.asarray(getattr(fr, key).values, float)
        friction[key] = [float(x) for x in np.round(base * _factors(rng, n, FACTOR_RANGE), 6)]
    # breakaway must stay above the kinetic friction it starts from
    for d in ("pos", "neg"):
        friction[f"static_{d}"] = [max(s, 1.05 * c) for s, c in
                                   zip(friction[f"static_{d}"], friction[f"coulomb_{d}"])]
    from rci.simula.arm import gravity_moves

    movable = gravity_moves(m)      # simula moves a centre of mass for these; the others fix masses
    gravity = {name: float(round(c.value * _factors(rng, 1, GRAVITY_RANGE)[0], 5))
               for name, c in m.gravity_coeffs.items() if name in movable}
    sgn = lambda k: rng.choice((-1.0, 1.0), k)  # noqa: E731
    kin = {"dtheta": sgn(n) * rng.uniform(0.05, 0.25, n) * DEG, "dd": sgn(n) * rng.uniform(0.0, 0.5e-3, n),
           "da": sgn(n) * rng.uniform(0.1e-3, 0.4e-3, n), "dalpha": sgn(n) * rng.uniform(0.03, 0.1, n) * DEG}
    revolute = np.array([k == "revolute" for k in m.kinds])
    kin = {k: np.where(revolute, v, 0.0) for k, v in kin.items()}   # simula has no DH errors for a slide
    return {"calib": {"schema": SCHEMA, "robot": robot,
                      "hidden_truth": f"rcci.calib.hidden_truth seed {seed}: sigma and friction 10-30 %, "
                                      "gravity 3-10 % away from the data file (those simula can move)"},
            "motors": {"torque_sensitivity": [float(x) for x in np.round(sigma, 6)]},
            "friction": friction,
            "gravity_coeffs": gravity,
            "kinematics": {k: [float(x) for x in np.round(v, 8)] for k, v in kin.items()}}


def write_hidden_truth(path: str, robot: str, seed: int, inertials: bool = False) -> dict:
    """Write :func:`hidden_truth` (with :func:`hidden_inertials` if ``inertials``) to ``path``
    (atomically) and return its tables."""
    from rcci.calib.params import atomic_write

    data = hidden_truth(robot, seed)
    if inertials:
        data.update(hidden_inertials(robot, seed))
        data["calib"]["hidden_truth"] += "; link masses 5-15 %, inertias and rotors 10-30 %"
    flag = " --inertials" if inertials else ""
    atomic_write(path, f"# a hidden truth of {robot} (calib hidden-truth --seed {seed}{flag}); docs/calib.md\n\n"
                       + dumps(data))
    return data


def add_hidden_truth(sub) -> None:
    """Register `hidden-truth` on the `calib` parser (``sub``: its subparsers)."""
    p = sub.add_parser("hidden-truth", help="write a simula parameter file drawn away from the data file")
    p.add_argument("--robot", default="puma260")
    p.add_argument("--seed", type=int, required=True, help="the draw (one seed, one truth)")
    p.add_argument("-o", "--out", required=True, metavar="FILE", help="parameter file to write")
    p.add_argument("--inertials", action="store_true",
                   help="also move the link masses, inertias and rotor inertias (for `calib fit dynamics`)")
    p.set_defaults(func=_main)


def _main(args) -> int:
    from rcci.calib.exceptions import CalibError
    from rcci.calib.params import writable_params
    from rcci.calib.robot import robot_info

    robot_info(args.robot)              # an arm calib cannot model is refused
    writable_params(args.out)
    try:
        write_hidden_truth(args.out, args.robot, args.seed, inertials=args.inertials)
    except ValueError as exc:
        raise CalibError(str(exc)) from None
    print(f"wrote {args.out}: a truth of {args.robot} (seed {args.seed}); record against it with "
          f"calib record all --simula \"--params {args.out} --seed N\"")
    return 0
