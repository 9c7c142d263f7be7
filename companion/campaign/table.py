"""The campaign table ``OUT/runs.parquet``: one row per run, rewritten whole and atomically.

Rows are dicts of scalars (:mod:`companion.campaign.measures`); the table is read back as
the same dicts. A write goes to ``runs.parquet.tmp`` beside the table, is flushed to disk,
then replaces the table in one ``os.replace``: a reader (or a campaign interrupted in the
middle of a write) sees the old table or the new one, never half of one. Rows are kept in
(mission, scenario, seed, run id) order, whatever order the runs finished in.

Column types: the columns saying what was run have fixed types (:data:`FIXED_TYPES`); a
measure is bool, int64 or float64 from its values (float64 while it has none).
"""

from __future__ import annotations

import os
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from companion.contracts.errors import UserError

TABLE = "runs.parquet"
_STR, _INT, _FLOAT = pa.string(), pa.int64(), pa.float64()
FIXED_TYPES: dict[str, pa.DataType] = {
    "run_id": _STR, "mission": _STR, "scenario": _STR, "seed": _INT, "duration_s": _FLOAT,
    "profile": _STR, "sim_params": _STR, "faults": _STR, "mission_path": _STR,
    "mission_sha256": _STR, "generator_seed": _INT, "generator_kind": _STR,
    "generator_max_loop_km": _FLOAT, "command": _STR, "error": _STR, "wall_s": _FLOAT,
}  # fmt: skip


def read_rows(path: Path) -> list[dict]:
    """The rows of the table at ``path`` ([] if there is none yet).

    Raises:
        UserError: the file is not a Parquet table with a ``run_id`` column.
    """
    if not path.exists():
        return []
    try:
        table = pq.read_table(path)
    except (OSError, pa.ArrowException) as exc:
        raise UserError(f"{path}: not a readable Parquet table ({exc})") from None
    if "run_id" not in table.column_names:
        raise UserError(f"{path}: not a campaign table (no run_id column)")
    return table.to_pylist()


def write_rows(path: Path, rows: list[dict]) -> None:
    """Replace the table at ``path`` with ``rows`` (atomically; see the module)."""
    rows = sorted(rows, key=lambda r: (r["mission"], r["scenario"], r["seed"], r["run_id"]))
    names = list(dict.fromkeys(k for r in rows for k in r))
    schema = pa.schema([(n, FIXED_TYPES.get(n) or _infer([r.get(n) for r in rows])) for n in names])
    table = pa.Table.from_pylist(rows, schema=schema)
    tmp = path.with_name(path.name + ".tmp")
    pq.write_table(table, tmp)
    with open(tmp, "rb") as fh:
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def _infer(values: list[object]) -> pa.DataType:
    have = [v for v in values if v is not None]
    if have and all(isinstance(v, bool) for v in have):
        return pa.bool_()
    if have and all(isinstance(v, int) and not isinstance(v, bool) for v in have):
        return _INT
    if all(isinstance(v, int | float) and not isinstance(v, bool) for v in have):
        return _FLOAT
    return _STR
