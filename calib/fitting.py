"""One fit of one kind over a set of logs: the results, their table, their parameter sections.

The kinds themselves are the modules of :mod:`rcci.calib.fits` (rcci.calib.registry); this module
runs one of them with the inputs it needs from earlier fits.

A fit that needs values from an earlier fit (the torque sensitivities turn currents into
torques; the gravity coefficients are subtracted at a halt or a breakaway) takes them from
the parameter file, and only from there: when the file lacks them the fit is refused
with a message that names the missing values and the command that fits them. With
``assume_datafile`` the robot data file's values (the thesis's tables) are used instead,
and the fit says so: in its printed notes and in the parameter file's
``[calib] assumed``. A value the parameter file holds as NaN (a joint not fitted) counts
as missing.
"""
from __future__ import annotations

import os

import numpy as np

from rcci.calib import registry
from rcci.calib.exceptions import CalibError
from rcci.calib.logs import motors_of
from rcci.calib.outcome import FitOutcome
from rcci.calib.robot import RobotInfo
from rcci.calib.trace import Trace

# what fits each input, for the refusal's message
PROVIDER = {"sigma": "sensitivity", "gravity": "gravity"}


class Inputs:
    """The values a fit takes from earlier fits (via the parameter file), with the rule
    above; ``assumed`` lists what came from the data file instead."""

    def __init__(self, info: RobotInfo, params: dict | None, kind: str, assume_datafile: bool,
                 params_name: str | None, logs: str, folder: str = ".", truth: str = "") -> None:
        self.info, self.params, self.kind = info, params or {}, kind
        self.assume, self.params_name, self.logs = assume_datafile, params_name, logs
        self.folder, self.truth = folder, truth
        self.assumed: list[str] = []
        self.mixed: list[str] = []     # inputs fitted on logs of another truth than this fit's

    def _same_truth(self, provider: str, what: str) -> None:
        """Note when ``what`` comes from a fit (``provider``) whose logs were recorded against
        another truth than this fit's: the values are another arm's (or another simula's)."""
        theirs = self.params.get("calib", {}).get(f"truth_{provider}")
        if theirs is None or not self.truth or theirs == self.truth:
            return
        note = (f"{what} in {self.params_name} were fitted on logs recorded against {theirs}, "
                f"these logs against {self.truth}: the result mixes two truths (refit {provider} "
                "on logs of this truth)")
        if note not in self.mixed:
            self.mixed.append(note)

    def _missing(self, what: str, which: str) -> CalibError:
        src = (f"the parameter file {self.params_name} does not hold them" if self.params_name
               else "no parameter file (-p) was given")
        fit = PROVIDER[what]
        return CalibError(
            f"calib fit {self.kind} needs the fitted {which}, and {src}. Fit them "
            f"first from logs recorded against the same arm as these (the same robot, or the same "
            f"simula truth and seed), e.g.:\n    calib fit {fit} {os.path.join(self.folder, fit + '-*.rcilog*')} "
            f"-p {self.params_name or 'fitted.toml'}\n"
            f"then run this fit with the same -p; or pass --assume-datafile to use the robot data "
            f"file's values (models/{self.info.name}.toml, the thesis's tables), which the output "
            "and the parameter file will then say were assumed")

    def sigma(self, joints: list[int]) -> np.ndarray:
        """Torque sensitivities (n,) N m/A for the motors that load ``joints`` (0-based)."""
        nominal = np.asarray(self.info.drive.sigma, dtype=float)
        got = self.params.get("motors", {}).get("torque_sensitivity")
        sigma = np.full(len(nominal), np.nan) if got is None else np.asarray(got, dtype=float)
        need = motors_of(joints, self.info.drive.G)
        gap = [m for m in need if not np.isfinite(sigma[m])]
        if gap:
            names = ", ".join(str(m + 1) for m in gap)
            if not self.assume:
                raise self._missing("sigma", f"torque sensitivities of motor(s) {names} (Table 4.1)")
            sigma[gap] = nominal[gap]
            self.assumed.append(f"{self.kind}: torque sensitivity of motor(s) {names} = "
                                + ", ".join(f"{nominal[m]:.4f}" for m in gap)
                                + f" N m/A, Table 4.1 from models/{self.info.name}.toml")
        if len(gap) < len(need):
            self._same_truth("sensitivity", "the torque sensitivities")
        # motors that load none of the fitted joints do not enter: any finite stand-in
        return np.where(np.isfinite(sigma), sigma, nominal)

    def sigma_scale_error(self, joints: list[int]) -> float:
        """The printed (99.73 %) relative uncertainty the fitted torque sensitivities of the
        motors of ``joints`` pass on to every torque, so to every coefficient fitted from
        them: the largest of their standard errors (std / sqrt(trials)) times the coverage
        factor of their trials. 0 for values the data file stood in for (announced as
        assumed: no honest error exists for them). The a priori scale errors of 4.5.2's
        independent error (mass, drum radius, current scale) are common to every torque and
        are not included (docs/calib.md)."""
        from rcci.calib.lsq import coverage_factor

        m = self.params.get("motors", {})
        n = len(self.info.drive.sigma)
        sigma = np.asarray(m.get("torque_sensitivity", [np.nan] * n), dtype=float)
        std = np.asarray(m.get("torque_sensitivity_std", [np.nan] * n), dtype=float)
        trials = np.asarray(m.get("torque_sensitivity_trials", [0] * n), dtype=float)
        worst = 0.0
        for k in motors_of(joints, self.info.drive.G):
            if np.isfinite(sigma[k]) and np.isfinite(std[k]) and trials[k] >= 2:
                worst = max(worst, coverage_factor(int(trials[k]) - 1) * std[k] / np.sqrt(trials[k]) / sigma[k])
        return float(worst)

    def regressor(self):
        """The gravity regressor of 4.24 at the arm's true joint angles: q plus the fitted joint
        offsets (d theta of ``[kinematics]``) when the parameter file has a kinematic
        calibration (a sweep's start torque is c sin or cos of the true angle), else at q."""
        kin = self.params.get("kinematics", {})
        if "dtheta" not in kin:
            return self.info.regressor
        self._same_truth("kinematics", "the joint offsets (d theta of [kinematics])")
        offset = np.nan_to_num(np.asarray(kin["dtheta"], dtype=float))
        reg = self.info.regressor
        return lambda q: reg(np.asarray(q, dtype=float) + offset)

    def gravity_model(self):
        """tau_g(q) (N m) with the fitted coefficients at the true joint angles."""
        c = self.gravity()
        reg = self.regressor()
        return lambda q: np.asarray(reg(q)) @ c

    def gravity(self) -> np.ndarray:
        """Gravity loading coefficients of the arm's regressor (``info.gravity_names``; PUMA 260:
        c12, c13, c15), N m (N on a prismatic joint)."""
        names = self.info.gravity_names
        got = self.params.get("gravity_coeffs", {})
        vals = np.array([float(got.get(n, np.nan)) for n in names])
        gap = [n for n, v in zip(names, vals) if not np.isfinite(v)]
        if len(gap) < len(names):
            self._same_truth("gravity", "the gravity coefficients")
        if gap:
            if not self.assume:
                raise self._missing("gravity", f"gravity loading coefficients {', '.join(gap)} (Table 4.9)")
            nominal = {n: float(self.info.nominal["gravity_coeffs"][n]["value"]) for n in names}
            for k, n in enumerate(names):
                if n in gap:
                    vals[k] = nominal[n]
            self.assumed.append(f"{self.kind}: gravity coefficients " + ", ".join(f"{n} = {nominal[n]:.3f}" for n in gap)
                                + f" N m, from models/{self.info.name}.toml")
        return vals


def merge_joint_values(old: dict | None, key: str, joints: list[int], new: list[float], n: int = 6) -> list[float]:
    """A per-joint list: the file's old values (NaN where it had none: not fitted), with
    the fitted ``joints`` (1-based) replaced."""
    arr = np.array(old[key], dtype=float) if old and key in old else np.full(n, np.nan)
    for j, v in zip(joints, new):
        arr[j - 1] = v
    return [float(x) for x in arr]


def log_set_notes(traces: list[Trace]) -> list[str]:
    """Warnings for logs recorded as a set (metadata ``log_set``: a joint's slow and servo-rate
    friction logs, a sensitivity run with and without the mass, a gravity sweep and its
    repeat) given without the rest of their set."""
    names = {(tr.experiment, str(tr.meta.get("log_name", ""))) for tr in traces}
    notes, seen = [], set()
    for tr in traces:
        for other in tr.meta.get("log_set", []) or []:
            if (tr.experiment, other) not in names and other not in seen:
                seen.add(other)
                notes.append(f"{tr.path}: recorded together with log {other!r}, which is not among the "
                             f"inputs: {registry.kind(tr.experiment).missing_log}")
    return notes


def run_fit(kind: str, traces: list[Trace], info: RobotInfo, params: dict | None,
            assume_datafile: bool = False, params_name: str | None = None) -> FitOutcome:
    """Fit ``kind`` (a name in rcci.calib.registry) on ``traces``; inputs from ``params`` (see the
    module docstring)."""
    from rcci.calib.truth import truth_label

    fit_kind = registry.kind(kind)
    logs = " ".join(os.path.basename(t.path) for t in traces)
    labels = sorted({truth_label(t) for t in traces})
    folders = sorted({os.path.dirname(t.path) or "." for t in traces})
    inputs = Inputs(info, params, kind, assume_datafile, params_name, logs, folders[0], "; ".join(labels))
    notes = log_set_notes(traces)
    if len(labels) > 1:
        notes.append(f"the {kind} logs were recorded against different truths ({'; '.join(labels)}): "
                     "one fit combines them")
    out = fit_kind.fit(traces, info, params or {}, inputs, notes)
    out.notes = notes + inputs.mixed + out.notes
    out.assumed = inputs.assumed
    out.truth = inputs.truth
    return out
