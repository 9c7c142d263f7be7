"""Campaigns: one patrol design flown hundreds of times (missions x scenarios x seeds).

Pure: ``scenarios.py`` (the disturbance matrix of ``bench/robustness.py``: named worlds as
simulator parameters), ``spec.py`` (the campaign YAML -> frozen dataclasses, one
:class:`~companion.contracts.errors.UserError` naming the file, line and field),
``grid.py`` (the spec expanded into run plans, each with a stable id and its
``companion simulate`` command line), ``measures.py`` (a run's ``metrics.json`` and alert
episodes -> one flat row) and ``summary.py`` (rows -> the per-scenario figures as text).

Edges: ``execute.py`` (each run through the in-memory engine in a Dask task, on an embedded
``distributed.LocalCluster`` or a running scheduler), ``table.py`` (the Parquet table
``OUT/runs.parquet``, rewritten atomically) and ``figure.py`` (``OUT/summary.png``).

See ``docs/campaigns.md``. This file imports none of them.
"""
