"""Random streams derived from a run's seed and the labels of what is being simulated.

A dry run must reproduce every sample from its seed, whatever happened before
(how many frames a simulator made while nobody read, a resumed session). So
each logged attempt draws from a stream of its own,
``SeedSequence([seed, stable hash of the step id, attempt])``: the same step and
attempt give the same draws in every run with that seed. Python's ``hash`` of
a string changes per process, so the step id is hashed with BLAKE2b.
"""

from __future__ import annotations

import hashlib

import numpy as np


def label_words(label: str) -> list[int]:
    """A stable 128-bit hash of ``label`` as four 32-bit words (SeedSequence entropy)."""
    digest = hashlib.blake2b(label.encode("utf-8"), digest_size=16).digest()
    return [int.from_bytes(digest[i:i + 4], "little") for i in range(0, 16, 4)]


def attempt_seed(seed: int, step_id: str, attempt: int) -> np.random.SeedSequence:
    """The stream of one attempt of one step of a run seeded with ``seed``."""
    if seed < 0 or attempt < 0:
        raise ValueError(f"seed and attempt must be >= 0, got {seed!r}, {attempt!r}")
    return np.random.SeedSequence([int(seed), *label_words(step_id), int(attempt)])
