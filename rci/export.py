"""Export a recorder log (``.rcilog``, docs/log-format.md) to the formats other tools read.

``.rcilog`` stays the crash-safe native format (CRC'd blocks, fsync'd while a control
runs); these are copies for looking at a run elsewhere:

* **MCAP** (``to_mcap``): one channel per record field, topic ``/rci/<field>`` (user fields
  ``/rci/user/<name>``), JSON messages ``{"value": ...}`` with a JSON schema per channel,
  one message per recorded cycle, log time = the cycle's host time ``t`` (ns since the log
  was created), publish time = the robot's clock. The log's header goes into an MCAP
  metadata record named ``rcilog``. Foxglove Studio and the ``mcap`` tools open it.
* **Parquet** (``to_parquet``): one row per cycle; a field with one value per joint (or
  ADC channel, ...) becomes one column per element, ``how_pos_1`` ... ``how_pos_6``
  (1-based, as the thesis numbers joints). The header is kept as the table's metadata
  (key ``rcilog``). ``pandas.read_parquet`` reads it.

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


def to_mcap(log: Log, out: str | os.PathLike) -> int:
    """Write ``log`` to the MCAP file ``out``; returns the number of messages written."""
    from mcap.writer import Writer

    rec = log.records
    names = rec.dtype.names
    t_ns = np.round(rec["t"] * 1e9).astype(np.int64)
    pub_ns = rec["robot_time_ns"].astype(np.int64)
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


def to_parquet(log: Log, out: str | os.PathLike) -> int:
    """Write ``log`` to the Parquet file ``out`` (one row per cycle); returns the row count."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.table({k: pa.array(v) for k, v in columns(log).items()})
    table = table.replace_schema_metadata({"rcilog": json.dumps(log.meta), "source": str(log.path)})
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
