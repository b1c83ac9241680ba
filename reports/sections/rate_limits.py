"""The maximum input rates' stated uncertainties (results.json ``uncertainty``).

The walk itself is reduced in ``analysis/rate/rate_limits.py``; this names its two
headline figures by their catalogue metrics.
"""

from __future__ import annotations

from gyrocal.analysis.rate.rate_limits import COVERAGE_K, RateLimitResults
from gyrocal.metrology.metrics import MAX_RATE_NEGATIVE, MAX_RATE_POSITIVE
from gyrocal.reports.sections.headline import StatedUncertainty

_METHOD = "rectangular over the rate walk (largest rate that follows to the first that does not)"


def rate_limits_uncertainty(section: RateLimitResults | None) -> list[StatedUncertainty]:
    """The walk's rectangular u and U = k·u of each direction's maximum (none when every
    rate walked followed: a lower bound has no interval)."""
    out: list[StatedUncertainty] = []
    if section is None:
        return out
    for metric, sign in ((MAX_RATE_POSITIVE, 1.0), (MAX_RATE_NEGATIVE, -1.0)):
        test = section.headline_test(sign)
        if test is not None and test.way.max_dps is not None and test.way.u_dps is not None:
            out.append(StatedUncertainty(metric, test.way.max_dps, test.way.u_dps,
                                         test.expanded_dps, COVERAGE_K, "deg/s", _METHOD))
    return out
