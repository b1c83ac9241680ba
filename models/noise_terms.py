"""The five IEEE Std 952 noise terms, named once.

Each term has three spellings that other tools and files already use: its
IEEE symbol (Q, N, B, K, R), its key under ``noise:`` in a model file
(``gyro-model.md``) and its key in a fit (``results.json`` ``allan.fit``,
``gyrocal analyze allan``, interfaces.md). They used to live in three lists in
three modules; this table is the only place that says which is which, so a
fourth scheme cannot drift from the other three.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class NoiseTerm:
    symbol: str         # IEEE Std 952 Annex C
    name: str
    model_key: str      # under ``noise:`` in a model file
    fit_key: str        # in a fit / results.json allan.fit
    unit: str


#: In the order of the Allan-variance columns (models/allan_theory.term_avar_columns).
NOISE_TERMS: tuple[NoiseTerm, ...] = (
    NoiseTerm("Q", "quantization noise", "quantization_arcsec", "Q_arcsec", "arcsec"),
    NoiseTerm("N", "angle random walk", "arw_deg_per_rth", "N_deg_per_rth", "deg/√h"),
    NoiseTerm("B", "bias instability", "bias_instability_dph", "B_dph", "deg/h"),
    NoiseTerm("K", "rate random walk", "rrw_deg_per_h_rth", "K_dph_per_rth", "deg/h/√h"),
    NoiseTerm("R", "rate ramp", "rate_ramp_dph_per_h", "R_dph_per_h", "deg/h/h"),
)
FIT_KEYS = tuple(t.fit_key for t in NOISE_TERMS)
MODEL_KEYS = tuple(t.model_key for t in NOISE_TERMS)
