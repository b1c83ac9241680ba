"""The run record: one owner for what a run leaves on disk.

A run folder holds the manifest, ``plan.json`` (the plan and what the report
needs from the procedure and station, frozen at start), the hash-chained
journal, sample chunks (Parquet, with a per-sample ``status`` column) and the
input copies. Everything that writes or reads them goes through this
package: ``run_folder`` (layout, manifest, chunks), ``journal`` (the chain and
the :class:`~gyrocal.record.journal.JournalEvent` catalogue),
``plan_record`` (plan.json, with a typed reader), ``logged_steps`` (which
attempt of a step counts) and ``atomic`` (crash-safe file writes). The
engine writes a record; ``reports/`` and the discrepancy workflow only read
one, and only through here (``tests/test_layout.py`` checks it).
"""
