"""The registry of fits: every module of :mod:`rcci.calib.fits` declares one kind of fit.

A kind is one :class:`FitKind` record, named ``KIND`` at the top level of its module in
``calib/fits/``. It says everything the commands need to know about that fit: the name
its logs carry (metadata ``experiment``) and the CLI takes, the parameter-file section it
writes and the per-joint keys it merges there, the fit itself, its section of
reports/calibration.md, its plots, and how its logs are recorded (on a robot with
``calib record`` and on simula with ``calib regen-logs``). Adding a fit is adding one
module there; ``calib fit``, ``calib record``, ``calib regen-logs`` and ``calib report``
find it through :func:`kinds`.

Three numbers place a kind among the others: ``order`` in the chained fit of
``calib report`` (each fit's inputs fitted before it: sensitivities before everything
that turns currents into torques, gravity before what subtracts it), ``record_order``
in ``calib regen-logs`` (programs that share one simula keep its state from one to the
next, so their order is part of the shipped logs' bytes) and ``report_order`` (the
thesis's table order in the report).
"""
from __future__ import annotations

import argparse
import importlib
import pkgutil
from dataclasses import dataclass, field
from functools import cache
from typing import TYPE_CHECKING, Any, Callable

from rcci.calib.exceptions import CalibError

if TYPE_CHECKING:   # annotations only: the records these callables take and give
    from rcci.calib.outcome import FitOutcome
    from rcci.calib.plan import MeasurementPlan
    from rcci.calib.robot import RobotInfo
    from rcci.calib.trace import Trace
    from rcci.calib.truth import GroundTruth


@dataclass
class ReportContext:
    """What a kind's report section may use besides its own outcome."""

    info: "RobotInfo"
    truth: "GroundTruth | None"           # None: logs of a robot, nothing to score against
    check: Callable[[str, bool], str]     # check(table, flag) -> "yes"/"**no**", counted for the summary
    traces: list["Trace"]                 # every log of the report
    plots: dict[str, list[str]]           # kind -> its plot files, relative to the report
    params_path: str                      # the chained parameter file
    quiet: bool = True
    no_accuracy: bool = False             # skip runs on simula that only the report makes


@dataclass
class RecordRequest:
    """``calib record KIND --url URL``: what the kind's recorder gets."""

    url: str
    out: str                      # folder for the logs
    robot: str
    info: "RobotInfo"
    joints: list[int]             # 1-based
    args: argparse.Namespace      # the command's options (rate, mass, halts, touches...)
    extra_meta: dict[str, Any]    # metadata every log carries (the truth it was recorded against)


@dataclass(frozen=True)
class RecordOptions:
    """The options of ``calib record ... --simula`` a kind's programs honour (None: its default).
    Each kind refuses, before recording, the ones it cannot honour (rcci.calib.cli_extra.OPTIONS)."""

    joints: tuple[int, ...] | None = None   # 1-based
    mass: float | None = None               # kg on the pulley (sensitivity)
    radius: float | None = None             # m, the pulley's drum (sensitivity)
    rate: int | None = None                 # Hz, readings per second of the log
    halts: int | None = None                # random halts (static)
    touches: int | None = None              # touches in all (kinematics)


@dataclass
class RegenContext:
    """``calib regen-logs`` / ``calib record --simula``: where a kind's simula logs go, what they
    are recorded against, the options given and which logs are already recorded."""

    out_dir: str
    work: str                     # scratch folder for the raw logs before compression
    seed: int
    params: str | None            # simula's parameter file (None: the robot data file)
    info: "RobotInfo"
    options: RecordOptions = field(default_factory=RecordOptions)
    notes: list[str] = field(default_factory=list)   # what a kind changed in its plans, and why
    resume: bool = False          # logs already in out_dir are not recorded again

    def joints(self) -> list[int]:
        """The joints to record (1-based): the options' or all."""
        return list(self.options.joints or range(1, len(self.info.lower) + 1))

    def measured_joints(self, kind: str) -> list[int]:
        """:meth:`joints` less those whose torque calib does not measure (rcci.calib.unmeasured):
        without --joints each is left out with its reason in ``notes``, with --joints refused."""
        from rcci.calib.unmeasured import why_unmeasured

        out = [j for j in self.joints() if why_unmeasured(self.info.name, j) is None]
        left = [j for j in self.joints() if j not in out]
        if left:
            why = (f"robot {self.info.name}: joint(s) {', '.join(map(str, left))}: torque not measured: "
                   f"{why_unmeasured(self.info.name)}")
            if self.options.joints or not out:
                raise CalibError(why)
            if f"{kind}: not recorded: {why}" not in self.notes:
                self.notes.append(f"{kind}: not recorded: {why}")
        return out

    def per_joint(self, kind: str, plan: Callable[[int], list]) -> list:
        """``plan(j)`` for each joint; without --joints a joint the arm cannot support is left
        out with its reason in ``notes`` (CalibError when none is left), with --joints refused."""
        out, why = [], []
        for j in self.joints():
            try:
                out += plan(j)
            except CalibError as exc:
                if self.options.joints:
                    raise
                why.append(str(exc))
        if not out:
            raise CalibError("; ".join(why))
        self.notes += [f"{kind}: not recorded: {w}" for w in why]
        return out


@dataclass(frozen=True)
class OwnSimula:
    """A program a kind records on a simula of its own (breakaway ramps, touches): ``run()``
    records the log ``name`` into the context's folder; returned by ``regen`` with the key
    ("own",) so that the campaign plans, counts, resumes and shows it with the others."""

    name: str
    run: Callable[[], None]
    logs: tuple[str, ...] = ()    # the logs it writes (default: ``name`` alone)

    def log_names(self) -> tuple[str, ...]:
        return self.logs or (self.name,)


@dataclass(frozen=True)
class FitKind:
    """One kind of fit (module docstring). Callables:

    * ``fit(traces, info, params, inputs, notes) -> FitOutcome``: ``params`` the parameter
      file's tables ({} if none), ``inputs`` the earlier fits' values (rcci.calib.fitting.Inputs),
      ``notes`` a list to append warnings to.
    * ``report(ctx, outcome) -> list[str]``: Markdown lines of its report section.
    * ``plot(outcome, folder, prefix) -> list[str]``: the files written (None: no plots).
    * ``record(request) -> None``: record its logs on the robot at ``request.url``.
    * ``regen(ctx) -> list[(simula_args, MeasurementPlan | OwnSimula)]``: plans to run on simula,
      in order; a program that needs a simula of its own is an OwnSimula under the key ("own",).
      Nothing is recorded by ``regen`` itself, so a campaign refuses before its first log.
    * ``fit_files(paths, robot)``: see the field.
    """

    name: str
    title: str                    # one line for --help
    section: str                  # the parameter-file table it writes
    merge_keys: tuple[str, ...]   # its per-joint keys in that table (others' fits keep theirs)
    order: int
    record_order: int
    report_order: int
    fit: Callable[..., "FitOutcome"]
    report: Callable[[ReportContext, "FitOutcome"], list[str]]
    record: Callable[[RecordRequest], None]
    regen: Callable[[RegenContext], list[tuple[tuple[str, ...], "MeasurementPlan"]]]
    plot: Callable[["FitOutcome", str, str], list[str]] | None = None
    #: inputs that are not logs (kinematics: CSV files of measured poses, which do not say their
    #: arm): (paths, robot) -> (results, table text, parameter-file sections); None: logs only
    fit_files: Callable[[list[str], str], tuple[Any, str, dict[str, dict[str, Any]]]] | None = None
    missing_log: str = "the fit lacks its measurements"   # what a log set given only in part costs


@cache
def _registry() -> dict[str, FitKind]:
    import rcci.calib.fits as package

    found: dict[str, FitKind] = {}
    for module in pkgutil.iter_modules(package.__path__):
        kind = getattr(importlib.import_module(f"{package.__name__}.{module.name}"), "KIND", None)
        if not isinstance(kind, FitKind):
            raise CalibError(f"calib/fits/{module.name}.py: declares no KIND = FitKind(...)")
        if kind.name in found:
            raise CalibError(f"calib/fits/{module.name}.py: a second fit named {kind.name!r}")
        found[kind.name] = kind
    return found


def kinds(by: str = "order") -> list[FitKind]:
    """Every kind, sorted by ``by`` (``order``, ``record_order`` or ``report_order``)."""
    return sorted(_registry().values(), key=lambda k: getattr(k, by))


def names(by: str = "order") -> tuple[str, ...]:
    """The kinds' names (the CLI's choices and the logs' ``experiment``)."""
    return tuple(k.name for k in kinds(by))


def kind(name: str) -> FitKind:
    """The kind called ``name``, or a CalibError listing the known ones."""
    try:
        return _registry()[name]
    except KeyError:
        raise CalibError(f"unknown fit kind {name!r}; one of {', '.join(names())}") from None
