"""The commands: one module per command family, called by ``gyrocal.cli`` (argument parsing only) and the demo.

The top of the stack: it may use the orchestrator (run, resume, validate, plan), the
reports (build, verify, certificate), the run record and the live page (``watch/``).
"""
