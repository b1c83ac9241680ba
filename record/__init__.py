"""The run record: one owner for what a run leaves on disk.

A run folder holds the manifest, ``plan.json`` (the plan and what the report
needs from the procedure and station, frozen at start), the hash-chained
journal, sample chunks (Parquet, with a per-sample ``status`` column) and the
input copies. Everything that writes or reads them goes through this
package: ``run_folder`` (layout, manifest, chunks written), ``samples`` (chunks
read: the one reader of them), ``journal`` (the chain and the
:class:`~gyrocal.record.journal.JournalEvent` catalogue),
``plan_record`` (plan.json, with its one typed reader ``load_plan_record``),
``logged_steps`` (which attempt of a step counts: the engine's resume and every
reader use the same rule) and ``atomic`` (crash-safe file writes). The engine
writes a record; ``reports/``, the discrepancy workflow and the live page only
read one, and only through here (``tests/test_layout.py`` checks it, and that
no other product module imports pyarrow but the external-log readers).
"""
