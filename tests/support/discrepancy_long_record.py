"""A long, low-rate control profile of our own (issue 29: controls on a long record).

The second held-out set's first run found effect-free controls `unexplained` on
a profile at 2.5 Hz for 20 h with a plateau temperature cycle (published in
docs/discrepancy-validation.md). That set's generators stay unread; this is our
own profile of the same kind, with parameters chosen here: 2.5 Hz, a
20 → 45 → 20 → −5 → 20 °C cycle at 0.4 °C/min with long plateaus, and in each
plateau a 10-minute static hold, ±0.3, 4, 40 and 250 deg/s dwells of 90 s, one
turn at 1.5 deg/s and an 8 deg/s² table.
"""

from __future__ import annotations

import discrepancy_scenarios as scenarios

#: the profile's keyword arguments besides its duration (``long_record_profile``)
LONG_RECORD = dict(fs_hz=2.5, setpoints_c=(20.0, 45.0, 20.0, -5.0, 20.0), ramps_c_per_min=(0.4, 0.4, 0.4, 0.4),
                   rates_dps=(0.3, 4.0, 40.0, 250.0), dwell_s=90.0, static_s=600.0, slow_rate_dps=1.5,
                   accel_dps2=8.0)


def long_record_profile(hours: float = 20.0) -> scenarios.Profile:
    """The profile over ``hours`` (shorter runs keep its shape: plateaus shrink, ramps stay)."""
    return scenarios.procedure_profile(duration_s=hours * 3600.0, **LONG_RECORD)
