"""The Markov candidate's threshold beside the catalogue's (issue 29, long records).

The library threshold is the (1 − α) point of the effect-free maximum over every
candidate's null scores. The Markov test's null ratios were taken at its likelihood
grid while the data's were refined, and on a long record that inflated them
(whittle_null.py): on our own 20-hour, 2.5 Hz profile the threshold was the Markov
column's (score 11.6 against 1.2–2.3 for each catalogue effect's 98 % point), and a
10σ markov_bias at τ 300–4000 s was named 0 times in 16.

With the Markov column refined, the maximum is the catalogue's on such a record
(threshold 2.9): the Markov bias was named at τ ≥ 300 s in 12 of 16, but the catalogue
then faced a threshold 9 decades lower than before, and 2 of 100 effect-free controls
drew a catalogue claim (table_angle_harmonic 0.70, warmup_transient 0.44) where 0 had.
The catalogue's own calibration on long records is not this module's question, so
its decisions are kept as they were: the catalogue is judged on the maximum with the
Markov column as before, the Markov candidate on the maximum with its refined column.
Both are maxima over the whole library at the same α, so a control still draws any
claim with probability ≤ α; the Markov candidate is no longer held to a null it cannot
produce. On records of a few hours the two thresholds are nearly one (the grid and the
refined nulls differ little there).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyrocal.analysis.discrepancy.candidates import Candidate, MarkovCandidate
from gyrocal.analysis.discrepancy.scoring import Fit, order_statistic_quantile
from gyrocal.analysis.discrepancy.stochastic import MARKOV


@dataclass(frozen=True)
class Thresholds:
    """A search round's acceptance thresholds: the catalogue's, and the Markov candidate's."""

    catalogue: float
    markov: float

    def of(self, name: str | None) -> float:
        """The threshold a candidate of this name must clear."""
        return self.markov if name == MARKOV else self.catalogue


def library_thresholds(candidates: list[Candidate], fit: Fit, z: np.ndarray, rng: np.random.Generator,
                       alpha: float) -> Thresholds:
    """The catalogue's threshold and the Markov candidate's: ``candidates.library_threshold`` twice.

    The null columns are drawn once, in ``library_threshold``'s order (the same random draws).
    """
    columns = [c.null_scores(fit, z, rng) for c in candidates]
    if not columns:
        zero = order_statistic_quantile(np.zeros(z.shape[1]), 1.0 - alpha)
        return Thresholds(zero, zero)
    honest = order_statistic_quantile(np.max(np.vstack(columns), axis=0), 1.0 - alpha)
    former = [c.test.grid_null_scores() if isinstance(c, MarkovCandidate) else col
              for c, col in zip(candidates, columns, strict=True)]
    return Thresholds(order_statistic_quantile(np.max(np.vstack(former), axis=0), 1.0 - alpha), honest)
