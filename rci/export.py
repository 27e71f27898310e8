"""Export a recorder log (``.rcilog``, docs/log-format.md) to the formats other tools read.

``.rcilog`` stays the crash-safe native format (CRC'd blocks, fsync'd while a control
runs); these are copies for looking at a run elsewhere:

* **MCAP** (``to_mcap``): the raw record, one channel per record field, topic
  ``/rci/<field>`` (user fields ``/rci/user/<name>``), JSON messages ``{"value": ...}`` with a
  JSON schema per channel; and the run in SI units (``rci.log_units``) on Foxglove's
  well-known schemas, so that Foxglove's 3D and plot panels show it without configuration:
  ``/joints/measured`` and ``/joints/commanded`` (``foxglove.JointStates``: position rad or m,
  velocity rad/s or m/s, effort N m or N; a field is left out where the log has no value),
  ``/tf`` (``foxglove.FrameTransforms``: the measured pose of each link in the one before,
  ``base_link`` -> ``link1`` -> ... -> ``link6``, the URDF's frames), ``/T6`` and
  ``/T6/commanded`` (``foxglove.FrameTransform``: frames ``T6`` and ``T6_commanded`` in
  ``base_link``), ``/motor_currents`` (A).
  One message per recorded cycle on each, log time = the cycle's host time ``t`` (ns since
  the log was created), publish time = the robot's clock. The log's header goes into an
  MCAP metadata record named ``rcilog``. Foxglove and the ``mcap`` tools open it.
* **Parquet** (``to_parquet``): one row per cycle; a field with one value per joint (or
  ADC channel, ...) becomes one column per element, ``how_pos_1`` ... ``how_pos_6``
  (1-based, as the thesis numbers joints); then the SI columns ``q_j``, ``qd_j``,
  ``q_cmd_j``, ``qd_cmd_j``, ``tau_j``, ``tau_cmd_j``, ``current_j`` and T6 as ``T6_x``,
  ``T6_y``, ``T6_z`` (m) and ``T6_qx`` ... ``T6_qw`` (unit quaternion), likewise
  ``T6_cmd_*``; each SI column's unit is in its field metadata (key ``unit``). The header
  is kept as the table's metadata (key ``rcilog``). ``pandas.read_parquet`` reads it.

Command line::

    python -m rci.export run.rcilog --mcap run.mcap --parquet run.parquet
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

from .exceptions import LogFormatError
from .log_units import LogSI, log_in_si, quaternion
from .recorder import Log, read_log

_JSON_TYPE = {"i": "integer", "u": "integer", "f": "number", "b": "boolean"}


def topic(field: str) -> str:
    """The MCAP topic of a record field (``u_<name>`` user fields under ``/rci/user/``)."""
    return f"/rci/user/{field[2:]}" if field.startswith("u_") else f"/rci/{field}"


def _schema(dt: np.dtype) -> dict:
    """JSON schema of one field's message: ``{"value": scalar or array of its shape}``."""
    item = {"type": _JSON_TYPE[dt.base.kind]}
    value = item
    for n in reversed(dt.shape):
        value = {"type": "array", "items": value, "minItems": n, "maxItems": n}
    return {"type": "object", "properties": {"value": value}, "required": ["value"]}


def to_mcap(log: Log, out: str | os.PathLike, si: LogSI | None = None) -> int:
    """Write ``log`` to the MCAP file ``out``: its raw fields and, on Foxglove's schemas, its SI
    channels (``si``: ``log_in_si(log)`` unless given). Returns the number of messages written."""
    from mcap.writer import Writer

    from .export_foxglove import channels as si_channels

    rec = log.records
    names = rec.dtype.names
    t_ns = np.round(rec["t"] * 1e9).astype(np.int64)
    pub_ns = rec["robot_time_ns"].astype(np.int64)
    si = si if si is not None else log_in_si(log)
    n = 0
    with open(out, "wb") as f:
        w = Writer(f)
        w.start(profile="", library="rcci rci.export")
        channels = {}
        for name in names:
            schema = w.register_schema(name=f"rci.{name}", encoding="jsonschema",
                                       data=json.dumps(_schema(rec.dtype[name])).encode())
            channels[name] = w.register_channel(topic=topic(name), message_encoding="json", schema_id=schema)
        columns = {name: rec[name].tolist() for name in names}
        for i in range(len(rec)):
            for name in names:
                w.add_message(channel_id=channels[name], log_time=int(t_ns[i]), publish_time=int(pub_ns[i]),
                              data=json.dumps({"value": columns[name][i]}).encode(), sequence=i)
                n += 1
        for channel_topic, schema_json, messages in si_channels(si, t_ns):
            schema = w.register_schema(name=schema_json["title"], encoding="jsonschema",
                                       data=json.dumps(schema_json).encode())
            channel = w.register_channel(topic=channel_topic, message_encoding="json", schema_id=schema)
            for i, message in enumerate(messages):
                if message is not None:
                    w.add_message(channel_id=channel, log_time=int(t_ns[i]), publish_time=int(pub_ns[i]),
                                  data=json.dumps(message, allow_nan=False).encode(), sequence=i)
                    n += 1
        w.add_metadata(name="rcilog", data={"header": json.dumps(log.meta), "source": str(log.path),
                                            "complete": str(log.complete).lower()})
        w.finish()
    return n


def columns(log: Log) -> dict[str, np.ndarray]:
    """The log as flat columns: an (N, k) field becomes ``name_1`` ... ``name_k``."""
    out: dict[str, np.ndarray] = {}
    rec = log.records
    for name in rec.dtype.names:
        col = rec[name]
        if col.ndim == 1:
            out[name] = col
        else:
            flat = col.reshape(len(col), -1)
            for j in range(flat.shape[1]):
                out[f"{name}_{j + 1}"] = flat[:, j]
    return out


def si_columns(si: LogSI) -> dict[str, tuple[np.ndarray, str]]:
    """The SI columns of a log, name -> (values, unit): ``q_j`` ... ``current_j`` (j from 1), T6 and
    the commanded T6 as position (m) and unit quaternion."""
    out: dict[str, tuple[np.ndarray, str]] = {}
    for name in ("q", "qd", "q_cmd", "qd_cmd", "tau", "tau_cmd", "current"):
        values = getattr(si, name)
        if values is None:
            continue
        units = ["A"] * values.shape[1] if name == "current" else si.unit(name)
        for j in range(values.shape[1]):
            out[f"{name}_{j + 1}"] = (values[:, j], units[j])
    for prefix, T in (("T6", si.T6), ("T6_cmd", si.T6_cmd)):
        for k, axis in enumerate("xyz"):
            out[f"{prefix}_{axis}"] = (T[:, k, 3], "m")
        quat = quaternion(T[:, :3, :3]) if len(T) else np.zeros((0, 4))
        for k, axis in enumerate("xyzw"):
            out[f"{prefix}_q{axis}"] = (quat[:, k], "1")
    return out


def to_parquet(log: Log, out: str | os.PathLike, si: LogSI | None = None) -> int:
    """Write ``log`` to the Parquet file ``out`` (one row per cycle: the raw columns, then the SI
    columns of ``si_columns``, each with its unit in the field metadata); returns the row count."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    si = si if si is not None else log_in_si(log)
    fields, arrays = [], []
    for k, v in columns(log).items():
        arrays.append(pa.array(v))
        fields.append(pa.field(k, arrays[-1].type))
    for k, (v, unit) in si_columns(si).items():
        arrays.append(pa.array(v))
        fields.append(pa.field(k, arrays[-1].type, metadata={"unit": unit}))
    schema = pa.schema(fields, metadata={"rcilog": json.dumps(log.meta), "source": str(log.path)})
    table = pa.Table.from_arrays(arrays, schema=schema)
    pq.write_table(table, out)
    return table.num_rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m rci.export", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("log", help="a recorder log (.rcilog, or .rcilog.xz / .gz)")
    ap.add_argument("--mcap", metavar="FILE", help="write an MCAP file (Foxglove, mcap tools)")
    ap.add_argument("--parquet", metavar="FILE", help="write a Parquet table (pandas, pyarrow)")
    args = ap.parse_args(argv)
    if not args.mcap and not args.parquet:
        ap.error("nothing to do: give --mcap FILE and/or --parquet FILE")
    for flag, module in ((args.mcap, "mcap"), (args.parquet, "pyarrow")):
        try:
            if flag:
                __import__(module)
        except ImportError:
            ap.error(f"the {module} package is missing: pip install 'rcci[export]'")
    try:
        log = read_log(args.log)
    except LogFormatError as exc:
        print(f"rci.export: {exc}", file=sys.stderr)
        return 2
    if not log.complete:
        print(f"rci.export: {args.log}: the recorder was not closed (crash?): exporting the "
              f"{len(log)} records written before", file=sys.stderr)
    for target, write, what in ((args.mcap, to_mcap, "messages"), (args.parquet, to_parquet, "rows")):
        if target:
            try:
                Path(target).parent.mkdir(parents=True, exist_ok=True)
                count = write(log, target)
            except OSError as exc:
                print(f"rci.export: cannot write {target}: {exc.strerror or exc}", file=sys.stderr)
                return 2
            print(f"wrote {target}: {count} {what} from {len(log)} cycles of {args.log}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
