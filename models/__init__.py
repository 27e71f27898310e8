"""The robot description (ground floor of the project): load a robot data file (``models/<name>.toml``) into frozen SI records.

A robot model is everything the rest of the system knows about one arm: the
Denavit-Hartenberg table of thesis Tables 3.1/3.2 (with the signs the A matrices
3.4-3.15 require), joint kinds and ranges, named poses, link inertials, the gravity
loading coefficients of eq. 4.24 (Table 4.9), the friction model of eq. 4.27
(Tables 4.2-4.6), motor torque sensitivities (Table 4.1) and the conversion constants
of section 4.4.3 / Appendix D.  Each robot has one TOML data file and one URDF.

Usage::

    from rcci.models import load_robot
    puma = load_robot("puma260")          # or "microbo", or a path to a .toml file
    puma.n_joints, puma.lower, puma.upper, puma.max_velocity    # SI numpy arrays
    puma.joints[2].kind, puma.joints[2].d, puma.joints[2].alpha  # joint 3 (0-based list)
    puma.poses["ready"]                   # (6,) joint values, rad / m
    puma.gravity_coeffs["c12"].value      # N*m
    puma.friction.coulomb_pos.values      # (6,) N*m or N
    puma.conversion.gear_ratio.values     # (6, 6) G of eq. 4.28
    puma.source("joints.3.d")             # Source(tag='thesis Table 3.1', why=...)
    puma.base_to_link(q)                  # (6, 4, 4) T_1..T_6 from the DH table (eq. 3.3, 4.9)

Conventions (SI, radians):

* DH convention of thesis eq. 3.3 (Paul's standard DH): ``A_i = Rz(theta_i) Tz(d_i)
  Tx(a_i) Rx(alpha_i)``.  For a revolute joint ``theta_i = joint.theta + q_i`` (``d``
  fixed); for a prismatic joint ``d_i = joint.d + q_i`` (``theta`` fixed).  Limits,
  velocities and poses are on ``q``.
* Frame 0 (URDF ``base_link``) has z0 up along the joint 1 axis; frames ``link1`` ..
  ``link6`` of the URDF coincide with DH frames 1..6.
* Joint numbers in source paths are the thesis's (1-based): ``"joints.3.d"`` is d3;
  ``model.joints`` is a 0-based tuple, ``model.joints[i].index == i + 1``.

Data-file schema (full description with examples in ``models/README.md``): every number
is a record ``{value = ..., unit = "...", source = "...", why = "...", uncertainty = ...}``
(or ``values = [...]`` with ``unit`` or per-entry ``units`` for vectors and matrices).
``source`` is ``"thesis <table/equation/section>"`` or ``"estimate"``; an estimate must
say ``why``.  Units are converted to SI on loading; a unit of the wrong dimension is an
error.  Any malformed or inconsistent file (missing field, wrong unit, NaN, lower >
upper, unknown joint kind, value without source, wrong number of joints, pose outside the
ranges, missing URDF or a URDF whose joints/limits/link frames/inertials disagree with the
data file)
raises :class:`rcci.models.ModelError` naming the file, the field and the problem.

Models are looked up in ``$RCCI_MODELS`` if set, else in this package's directory (the data
files ship as package data).

Modules, one concept each: ``units`` (units and dimensions), ``quantities`` (Source, Value,
Vector, Matrix), ``drive`` (the friction records of eq. 4.27), ``robot`` (Joint, LinkInertial,
Motors, Conversion, RobotModel), ``loader`` (data-file validation), ``urdf`` (the URDF check),
``catalogue`` (lookup and :func:`load_robot`), ``params`` (the calibration parameter file),
``kinematics`` (the contract of the generated kinematics modules), ``errors`` (ModelError).
Nothing here imports ``rci``, ``rccl``, ``calib`` or ``derive``.
"""
from __future__ import annotations

from .catalogue import available_robots, load_robot, models_dir
from .drive import FRICTION_KEYS, Friction, JointFriction
from .exceptions import ModelError
from .quantities import Matrix, Source, Value, Vector
from .robot import Conversion, Joint, LinkInertial, Motors, RobotModel
from .units import JOINT_KINDS, UNITS

__all__ = [
    "Source", "Value", "Vector", "Matrix", "Joint", "LinkInertial", "Friction", "Motors",
    "Conversion", "RobotModel", "load_robot", "models_dir", "available_robots", "UNITS",
    "JOINT_KINDS", "ModelError", "JointFriction", "FRICTION_KEYS",
]
