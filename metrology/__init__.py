"""Metrology: GUM uncertainty, uncertainty budgets, the metric catalogue, the decision rule, physical sense.

Sits above ``gyrocal.analysis`` (a budget propagates the analysis' fits) and below the
orchestrator (a procedure's acceptance limits name catalogue metrics) and the reports.
"""
