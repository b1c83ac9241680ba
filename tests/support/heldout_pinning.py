"""How a held-out validation set is pinned by digest (tests of sets T and U share it).

A held-out set is worth something only while it stays the set it was when it was
made: its tests hash its design (procedures, unknown shapes, parameters) and its
case list, so any change to them fails a test and has to be made on purpose. The
hashing lives here once; each set's test module keeps its own digests and counts.
"""

from __future__ import annotations

import dataclasses
import hashlib

import discrepancy_scenarios as scenarios
import numpy as np
from discrepancy_heldout import HeldOutSet

from gyrocal.models.gyro_model import EffectSpec

#: (sample rate Hz, duration s) of the tuning profiles P1–P3, Q1–Q3: a held-out profile must differ
EARLIER = {"P1": (5.0, 3600.0), "P2": (100.0, 9300.0), "P3": (200.0, 7200.0),
           "Q1": (20.0, 5400.0), "Q2": (50.0, 2700.0), "Q3": (10.0, 10800.0)}

#: per profile: (catalogue seeds, controls, unknown seeds, 5σ seeds), as the runner's defaults
Counts = dict[str, tuple[int, int, int, int]]


def fs_and_duration(prof: scenarios.Profile) -> tuple[float, float]:
    return round(prof.fs_hz, 6), round(prof.t_s[-1] + 1.0 / prof.fs_hz, 3)


def digest(parts: list[bytes]) -> str:
    h = hashlib.sha256()
    for part in parts:
        h.update(len(part).to_bytes(8, "little") + part)
    return h.hexdigest()


def array_bytes(x: np.ndarray) -> bytes:
    """As float32 (7 significant digits): the values, not the last bit of a library's arithmetic."""
    return np.asarray(x, dtype=np.float32).tobytes()


def design_parts(held: HeldOutSet) -> list[bytes]:
    """Procedures, unknown shapes (at the first unknown seed) and every parameter of the set."""
    parts = [repr((held.name, held.seed_base, held.shape_stream)).encode()]
    for name, prof in held.profiles.items():
        p = held.profile(name)
        parts += [repr(dataclasses.replace(prof, build=None)).encode(),
                  array_bytes(p.t_s), array_bytes(p.table_rate_dps), array_bytes(p.chamber_temp_c)]
        for uname, unknown in held.unknown.items():
            parts.append(repr((uname, unknown.sizing, unknown.with_effect, unknown.shape.__name__)).encode())
            if prof.runs_unknown(uname):
                parts.append(array_bytes(unknown.shape(p, held.shape_rng(held.seed_base + 500))))
    return parts


class UnsizedSet(HeldOutSet):
    """The set with each catalogue effect left at its SNR instead of sized: the case list without the
    sizing (the sizes are pinned by a slow test of their own)."""

    def catalogue_spec(self, name: str, pname: str, snr: float) -> EffectSpec:
        return EffectSpec(name, {"snr": snr})


def unsized(held: HeldOutSet) -> UnsizedSet:
    return UnsizedSet(**{f.name: getattr(held, f.name) for f in dataclasses.fields(HeldOutSet)})


def case_key(case, sized: bool) -> bytes:
    hidden = [(h.name, sorted((k, float(f"{v:.3g}")) for k, v in h.params.items()) if sized else None)
              for h in case.hidden]
    return repr((case.group, case.label, case.profile, case.seed, case.unknown, case.snr, hidden)).encode()


def default_cases(held: HeldOutSet, counts: Counts) -> list:
    cases = []
    for name, (seeds, controls, unknown_seeds, near) in counts.items():
        cases += held.cases(seeds, controls, unknown_seeds, profiles=(name,), near_seeds=near)
    return cases
