"""Reading recorder logs (docs/log-format.md) into Traces, with errors that say where."""
from __future__ import annotations

import gzip
import lzma
import os
import tempfile
import zlib
from collections.abc import Sequence

import numpy as np

from rcci.calib.exceptions import LogError, MixedLogsError
from rcci.calib import registry
from rcci.calib.trace import Trace, check_samples
from rci.exceptions import LogFormatError
from rci.recorder import read_log

#: the shipped logs (``calib regen-logs`` writes them, ``calib report`` reads them)
LOG_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "logs")
# ADC readings are 12-bit signed (docs/log-format.md): at the rails the current is unknown.
ADC_RAIL = 2047


def load_trace(path: str, allow_truncated: bool = False) -> Trace:
    """One log as a Trace.  Raises LogError for a damaged, truncated (unless allowed)
    or incomplete log, naming the file, the record and the problem."""
    try:
        log = _read(path)
    except LogFormatError as exc:
        raise LogError(path, None, f"{exc.where}: {exc.problem}") from None
    if not log.complete and not allow_truncated:
        note = log.notes[-1] if log.notes else "no end marker"
        raise LogError(path, len(log), f"truncated after record {len(log) - 1}: {note} "
                       "(refit with --allow-truncated to use the records before it)")
    header = log.meta
    meta = header.get("meta")
    if not isinstance(meta, dict):
        raise LogError(path, None, "header has no run metadata object 'meta' "
                       "(was the log written by a calib measurement program?)")
    experiment = meta.get("experiment")
    if experiment not in registry.names():
        raise LogError(path, None, f"metadata 'experiment' = {experiment!r} "
                       f"is not one of {', '.join(registry.names())}")
    rec = log.records
    names = rec.dtype.names or ()
    for col in ("cycle", "rate_hz", "how_pos", "how_adcr"):
        if col not in names:
            raise LogError(path, None, f"records lack the column '{col}'")
    if len(rec) == 0:
        raise LogError(path, None, "the log holds no records")
    counts = np.asarray(rec["how_pos"], dtype=float)
    adc = np.asarray(rec["how_adcr"], dtype=float)
    nj = counts.shape[1] if counts.ndim == 2 else 0      # the log's joints (its header's nj)
    if counts.ndim != 2 or nj < 6 or adc.ndim != 2 or adc.shape[1] < nj:
        raise LogError(path, None, f"records hold {counts.shape[1:]} positions and "
                       f"{adc.shape[1:]} ADC channels; a robot of 6 or more joints, with an ADC "
                       "channel per joint, is needed")
    rate_hz = header.get("rate_hz", 0) or 0
    if isinstance(rate_hz, bool) or not isinstance(rate_hz, (int, float)) or not np.isfinite(rate_hz) or rate_hz < 0:
        raise LogError(path, None, f"header 'rate_hz' = {rate_hz!r} is not a sample rate in Hz")
    trace = Trace(path=str(path), robot=str(header.get("robot", "")),
                  rate_hz=float(rate_hz), meta=meta,
                  t=_cycle_times(path, rec),
                  counts=counts, adc=adc[:, :nj])
    if "how_inport1" in names:
        trace.extra["inport1"] = np.asarray(rec["how_inport1"])
    if "u_touch" in names:                   # the touch index of a kinematics log
        trace.extra["touch"] = np.asarray(rec["u_touch"])
    if "chg_motion_com" in names and "chg_motion_value" in names:
        # the commands sent each cycle: a breakaway log's ramps are its CUR cycles
        trace.extra["motion_com"] = np.asarray(rec["chg_motion_com"])[:, :nj]
        trace.extra["motion_value"] = np.asarray(rec["chg_motion_value"], dtype=float)[:, :nj]
    check_samples(trace)
    return trace


def _cycle_times(path: str, rec: np.ndarray) -> np.ndarray:
    """Robot time (s) of each record from its cycle number and the sample rate.

    The robot's cycles are its clock (one HOW per sample period, A.4), so this is the
    time the joint moved in, for a real arm and for simula in lockstep alike (where the
    host's clock says nothing about the simulated motion).
    """
    cycle = np.asarray(rec["cycle"], dtype=np.int64)
    rate = np.asarray(rec["rate_hz"], dtype=float)
    if (rate <= 0).any():
        k = int(np.argmax(rate <= 0))
        raise LogError(path, k, f"sample rate {rate[k]:g} Hz is not positive")
    step = np.diff(cycle) % (1 << 32)   # the u4 counter may wrap
    if len(step) and (step == 0).any():
        k = int(np.argmax(step == 0)) + 1
        raise LogError(path, k, f"cycle {cycle[k]} repeats the previous record's")
    return np.concatenate([[0.0], np.cumsum(step / rate[:-1])])


def _read(path: str):
    """read_log, also for a compressed log: ``.xz`` (how calib/logs/ ships them: a third
    smaller than gzip on 1 kHz logs) or ``.gz``."""
    name = str(path)
    if not name.endswith((".gz", ".xz")):
        return read_log(path)
    kind = "xz" if name.endswith(".xz") else "gzip"
    try:
        if kind == "xz":
            with lzma.open(path, "rb") as f:
                data = f.read()
        else:
            with gzip.open(path, "rb") as f:
                data = f.read()
    except (OSError, EOFError, zlib.error, lzma.LZMAError) as exc:
        raise LogError(path, None, f"not a readable {kind} file: {exc}") from None
    with tempfile.NamedTemporaryFile(suffix=".rcilog") as tmp:
        tmp.write(data)
        tmp.flush()
        try:
            log = read_log(tmp.name)
        except LogFormatError as exc:
            raise LogFormatError(path, exc.where, exc.problem) from None
    log.path = str(path)
    return log


def load_traces(paths: Sequence[str], experiment: str | None = None,
                allow_truncated: bool = False) -> list[Trace]:
    """Several logs of one robot (and, if given, one experiment)."""
    if not paths:
        raise MixedLogsError("no log files given")
    traces = [load_trace(p, allow_truncated) for p in paths]
    robots = {tr.robot for tr in traces}
    if len(robots) > 1:
        by = "; ".join(f"{tr.path}: {tr.robot}" for tr in traces)
        raise MixedLogsError(f"logs from different robots cannot be fitted together ({by})")
    if experiment is not None:
        for tr in traces:
            if tr.experiment != experiment:
                raise LogError(tr.path, None, f"is a '{tr.experiment}' log, "
                               f"not a '{experiment}' one")
    return traces


def saturated_records(trace: Trace, joint: int) -> np.ndarray:
    """Indices of records whose ADC channel of ``joint`` (0-based) sits at a rail."""
    return np.flatnonzero(np.abs(trace.adc[:, joint]) >= ADC_RAIL)


def motors_of(joints, G: np.ndarray) -> list[int]:
    """The motors (0-based) whose torque reaches any of ``joints`` (0-based): t_j = G^T t_s,
    so motor m loads joint j where G[m, j] != 0 (on the PUMA's wrist, joint 4 needs motors
    4, 5 and 6)."""
    G = np.asarray(G)
    return sorted({m for j in joints for m in np.flatnonzero(G[:, j] != 0.0)})


def saturated_mask(trace: Trace, joints, G: np.ndarray) -> np.ndarray:
    """True for each record where an ADC channel of a motor of ``joints`` (0-based) sits at
    a rail: there the current (so the torque) is unknown, only bounded."""
    chans = motors_of(joints, G)
    return np.any(np.abs(trace.adc[:, chans]) >= ADC_RAIL, axis=1)


def clipped_note(trace: Trace, what: str, dropped: int, total: int, joints, G: np.ndarray) -> str:
    """The warning for ``dropped`` of ``total`` units (passes, halts, ramps) left out for
    readings at an ADC rail."""
    chans = ", ".join(str(m + 1) for m in motors_of(joints, G))
    return (f"{trace.path}: {dropped} of {total} {what} left out: ADC channel(s) {chans} read at "
            f"the rail (+-{ADC_RAIL}), where the current is unknown")
