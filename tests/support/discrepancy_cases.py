"""One run of a discrepancy validation set: what is hidden in the data, on which profile.

Shared by the validation benchmarks (``validate_discrepancy_outside.py``,
``validate_discrepancy_fresh.py``) and the tests of their sets, so that a case
means the same thing to the set that defines it and to the runner that scores it.
"""

from __future__ import annotations

from dataclasses import dataclass

from gyrocal.models.gyro_model import EffectSpec


@dataclass(frozen=True)
class Case:
    """One simulated log: catalogue effects in ``hidden``, structure outside the catalogue in ``unknown``.

    ``group`` is "effect" (catalogue effects only: each must be named), "control"
    (nothing hidden: any claim is false) or "unknown" (structure outside the
    catalogue, possibly beside a catalogue effect: it must be called unexplained,
    and only the names in ``hidden`` are right).
    """

    group: str
    label: str
    profile: str
    hidden: tuple[EffectSpec, ...]
    seed: int
    unknown: str = ""
    snr: float = 10.0

    def is_right(self, name: str) -> bool:
        """A claim of ``name`` is right when that effect was hidden in the data."""
        return name in {h.name for h in self.hidden}
