"""The threshold and resolution figures' stated uncertainties (results.json ``uncertainty``).

The test itself is reduced in ``analysis/rate/threshold.py``; this names its two headline
figures by their catalogue metrics.
"""

from __future__ import annotations

from gyrocal.analysis.rate.threshold import COVERAGE_K, ThresholdResults
from gyrocal.metrology.metrics import RESOLUTION, THRESHOLD
from gyrocal.reports.sections.headline import StatedUncertainty

_METHOD = "rectangular over the increment grid (largest failing to smallest passing increment)"


def threshold_uncertainty(section: ThresholdResults | None) -> list[StatedUncertainty]:
    """The grid's rectangular u and U = k·u of the threshold and the resolution."""
    out: list[StatedUncertainty] = []
    if section is None:
        return out
    for metric, zero in ((THRESHOLD, True), (RESOLUTION, False)):
        test = section.headline_test(zero=zero)
        if test is not None and test.threshold_dps is not None:
            out.append(StatedUncertainty(metric, test.threshold_dps, test.bracket.u_dps,
                                         test.expanded_dps, COVERAGE_K, "deg/s", _METHOD))
    return out
