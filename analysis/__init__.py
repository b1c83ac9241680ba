"""Analysis: the numbers a calibration needs, computed from samples (no report, no verdict).

Allan deviation and noise terms (``allan/``), rate tests — scale factor, dwells, threshold,
rate limits, frequency response (``rate/``), temperature effects — bias, warm-up,
compensation tables (``thermal/``), the vendor notes' environment tests (``environment/``),
multi-axis IMU fits (``imu/``), measured logs and their contract, and the discrepancy
workflow (``discrepancy/``). It reads runs only through ``gyrocal.record``; uncertainty
budgets and decisions live one layer up, in ``gyrocal.metrology``.
"""
