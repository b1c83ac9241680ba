"""What every held-out validation set of the discrepancy workflow is made of, and how it is sized.

A held-out set (issue 29) is a few procedures unlike the ones the workflow was
tuned on (``FreshProfile``), structure outside the catalogue (``Unknown``) and
the rule that turns them into runs (``HeldOutSet``): every catalogue effect
the profile can show at 10σ (some at 5σ), effect-free controls, each unknown
a few times. Once a set's runs have been read while the workflow changes it no
longer holds anything out, so a new set is needed; they share this machinery
so that each is sized, seeded and judged by the same rule (R1–R3 in
``discrepancy_fresh``, S1–S3 in ``discrepancy_fresh_s``).

Sizes follow ``discrepancy_scenarios``: catalogue effects by known-shape SNR
(``sized_effect``, ``sized_markov``); unknowns by the known-shape SNR of their
binned shape (``sized_extra``), a periodic one by its norm against the white
noise (what ``sized_effect`` does for periodic_interference), a noise-level
change by its expected likelihood ratio snr² (what ``sized_markov`` does).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache

import discrepancy_scenarios as scenarios
import numpy as np
from discrepancy_cases import Case

from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.analysis.discrepancy.scoring import gls_fit
from gyrocal.analysis.discrepancy.signatures import placeholder_spec
from gyrocal.models.gyro_model import EffectSpec

MAX_BINS = 1000       # the analysis' bins in the validation runs (sizes are SNRs of these bin means)

#: every sized catalogue effect; a profile drops those it gives nothing to act on
SIZED = ("thermal_lag", "temp_rate_bias", "temp_hysteresis", "bias_temp_quadratic",
         "sf_temp_quadratic", "sf_nonlinearity_quadratic", "sf_nonlinearity_cubic",
         "sf_asymmetry", "warmup_transient", "bias_ramp", "table_angle_harmonic",
         "periodic_interference")

#: thermal_lag's column in ``HeldOutSet.catalogue_columns``: its signature at this τ (the lag family's shape)
LAG_COLUMN_TAU_S = 300.0


def scheduled_profile(duration_s: float, fs_hz: float, temp_c: Callable[[np.ndarray], np.ndarray],
                      rate_cycle: tuple[tuple[float, float], ...], cycle_starts_s,
                      accel_dps2: float) -> scenarios.Profile:
    """A temperature path ``temp_c(t)`` and a cycle of (rate deg/s, seconds) table blocks at given starts.

    Unlike ``procedure_profile`` the table tests need not sit in soaks: they run
    wherever ``cycle_starts_s`` puts them (through a ramp, on a cycle); the table
    is held still elsewhere and slews at ``accel_dps2`` between blocks.
    """
    t = np.arange(int(round(duration_s * fs_hz))) / fs_hz
    rate = np.zeros_like(t)
    for start in cycle_starts_s:
        at = float(start)
        for rate_dps, length_s in rate_cycle:
            rate[(t >= at) & (t < at + length_s)] = rate_dps
            at += length_s
    return scenarios.Profile(t, scenarios._slewed(rate, fs_hz, accel_dps2), temp_c(t))


@dataclass(frozen=True)
class FreshProfile:
    """A procedure of a held-out set and the catalogue effects' parameters on it."""

    title: str
    build: Callable[[], scenarios.Profile]
    shapes: dict[str, dict[str, float]]      # shape parameters of the sized effects
    dead_zone_dps: float                      # swallows the profile's lowest dwell rate
    markov_taus_s: tuple[float, float]
    pulse_arcsec: float
    unobservable: tuple[str, ...] = field(default=())   # sized effects the profile cannot show
    #: unknowns the profile turns into catalogue effects (not run there; the reason is in PROFILES)
    catalogue_alike: tuple[str, ...] = field(default=())
    #: unknowns that have nothing to act on in this procedure (not run there; the reason is in PROFILES)
    not_applicable: tuple[str, ...] = field(default=())

    @property
    def sized(self) -> tuple[str, ...]:
        return tuple(n for n in SIZED if n not in self.unobservable)

    def runs_unknown(self, name: str) -> bool:
        return name not in self.catalogue_alike and name not in self.not_applicable


@dataclass(frozen=True)
class Unknown:
    """An out-of-catalogue shape (deg/h per sample before sizing) and how it is sized.

    ``sizing``: "bins" (known-shape SNR of its binned shape), "white" (norm
    against the per-sample white noise, for shapes that live above the bins'
    band), "noise" (``shape`` is a relative variance increase; sized by its
    expected likelihood ratio). ``with_effect``: a catalogue effect hidden
    beside it at the same SNR.
    """

    shape: Callable[[scenarios.Profile, np.random.Generator], np.ndarray]
    sizing: str = "bins"
    with_effect: str = ""


def white_sigma_dph(p: scenarios.Profile) -> float:
    return NoiseModel.of_model(scenarios.nominal_model()).white_sigma_dph(p.fs_hz)


def noise_scale(relative_var: np.ndarray, snr: float) -> float:
    """c for which Σ (c·r − ln(1 + c·r)) = snr²: the expected likelihood ratio of the variance change.

    2·KL between N(0, σ²(1 + c·r)) and N(0, σ²), summed over the samples.
    """
    def lr(c: float) -> float:
        cr = c * relative_var
        return float(np.sum(cr - np.log1p(cr)))
    lo, hi = math.log(1e-9), math.log(1e6)
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if lr(math.exp(mid)) < snr * snr else (lo, mid)
    return math.exp(0.5 * (lo + hi))


def sized_unknown(unknown: Unknown, p: scenarios.Profile, snr: float, rng: np.random.Generator) -> np.ndarray:
    """``unknown``'s structure on ``p`` (deg/h per sample) at size ``snr`` by its own sizing rule."""
    shape = unknown.shape(p, rng)
    if unknown.sizing == "bins":
        return scenarios.sized_extra(shape, snr, p, max_bins=MAX_BINS)
    sigma = white_sigma_dph(p)
    if unknown.sizing == "white":
        return shape * (snr * sigma / float(np.linalg.norm(shape)))
    return sigma * np.sqrt(noise_scale(shape, snr) * shape) * rng.standard_normal(shape.size)


@dataclass(frozen=True)
class SnrSpace:
    """The space the sizes are SNRs in, on one profile: binned, whitened, ⊥ the refitted base."""

    bins: object
    builder: object
    base: object
    base_bins: np.ndarray
    project_binned: Callable[[np.ndarray], np.ndarray]

    def project(self, shape_dph: np.ndarray) -> np.ndarray:
        """A per-sample shape (deg/h) → its whitened, base-projected bin means."""
        return self.project_binned(self.bins.mean(shape_dph))


def residual_snr(signal: np.ndarray, columns: np.ndarray) -> float:
    """Norm of what is left of ``signal`` once ``columns`` (orthonormal) are fitted to it."""
    return float(np.linalg.norm(signal - columns @ (columns.T @ signal)))


@dataclass(frozen=True, eq=False)
class HeldOutSet:
    """One held-out set: its profiles, its unknowns, and the seeds its runs draw.

    Runs are seeded from ``seed_base``: catalogue effects + k, Markov + 100 + k,
    dead zone + 200 + k, quantization + 300 + k, controls + 400 + k, unknowns
    + 500 + k; an unknown's random shape draws from ``[seed, shape_stream]``,
    apart from the simulator's noise of the same seed.
    """

    name: str
    profiles: dict[str, FreshProfile]
    unknown: dict[str, Unknown]
    seed_base: int
    shape_stream: int
    #: 0: every profile draws the same noise for a seed (R–U); else profile i's runs are seeded
    #: + i·stride, so one rare noise draw is not counted on every profile (V)
    profile_seed_stride: int = 0

    def run_seed(self, pname: str, offset: int) -> int:
        """The seed of a run ``offset`` above the base on profile ``pname`` (see ``profile_seed_stride``)."""
        return self.seed_base + offset + self.profile_seed_stride * tuple(self.profiles).index(pname)

    @cache  # noqa: B019 (a set lives as long as the process; its profiles are built once)
    def profile(self, name: str) -> scenarios.Profile:
        return self.profiles[name].build()

    def shape_rng(self, seed: int) -> np.random.Generator:
        """The random stream of a case's out-of-catalogue shape: apart from the simulator's noise of ``seed``."""
        return np.random.default_rng([seed, self.shape_stream])

    def extra_dph(self, name: str, p: scenarios.Profile, snr: float, seed: int) -> np.ndarray:
        """The out-of-catalogue structure ``name`` (deg/h per sample) at size ``snr``."""
        return sized_unknown(self.unknown[name], p, snr, self.shape_rng(seed))

    def catalogue_spec(self, name: str, pname: str, snr: float) -> EffectSpec:
        return scenarios.sized_effect(name, snr, self.profile(pname), shape=self.profiles[pname].shapes.get(name),
                                      max_bins=MAX_BINS)

    def effect_cases(self, pname: str, seeds: int, snr: float = 10.0) -> list[Case]:
        """Every catalogue effect the profile can show, alone, at ``snr``."""
        prof, cases = self.profiles[pname], []
        if seeds == 0:
            return cases
        for name in prof.sized:
            spec = self.catalogue_spec(name, pname, snr)
            cases += [Case("effect", f"{name} ({snr:g}σ)", pname, (spec,), self.run_seed(pname, s), snr=snr) for s in range(seeds)]
        for tau in prof.markov_taus_s:
            spec = scenarios.sized_markov(snr, tau, self.profile(pname))
            cases += [Case("effect", f"markov_bias τ {tau:g} s ({snr:g}σ)", pname, (spec,), self.run_seed(pname, 100 + s),
                           snr=snr) for s in range(seeds)]
        if snr == 10.0:
            spec = EffectSpec("dead_zone", {"threshold_dps": prof.dead_zone_dps})
            cases += [Case("effect", f"dead_zone {prof.dead_zone_dps:g} deg/s", pname, (spec,), self.run_seed(pname, 200 + s))
                      for s in range(seeds)]
            spec = EffectSpec("quantization", {"pulse_arcsec": prof.pulse_arcsec})
            cases += [Case("effect", f"quantization {prof.pulse_arcsec:g}″", pname, (spec,), self.run_seed(pname, 300 + s))
                      for s in range(seeds)]
        return cases

    def cases(self, seeds: int, controls: int, unknown_seeds: int, profiles: tuple[str, ...] | None = None,
              near_seeds: int = 0, near_snr: float = 5.0) -> list[Case]:
        """Per profile: the catalogue at 10σ (``near_seeds`` also at ``near_snr``),
        ``controls`` effect-free runs and every unknown the profile runs ``unknown_seeds`` times."""
        cases: list[Case] = []
        for pname in profiles or tuple(self.profiles):
            cases += self.effect_cases(pname, seeds)
            if near_seeds:
                cases += self.effect_cases(pname, near_seeds, near_snr)
            cases += [Case("control", "control", pname, (), self.run_seed(pname, 400 + s)) for s in range(controls)]
            for name, unknown in self.unknown.items():
                if not self.profiles[pname].runs_unknown(name) or unknown_seeds == 0:
                    continue
                hidden = (self.catalogue_spec(unknown.with_effect, pname, 10.0),) if unknown.with_effect else ()
                cases += [Case("unknown", name, pname, hidden, self.run_seed(pname, 500 + s), name)
                          for s in range(unknown_seeds)]
        return cases

    def case_extra_dph(self, case: Case) -> np.ndarray | None:
        """The case's structure outside the catalogue (None for effects and controls)."""
        return self.extra_dph(case.unknown, self.profile(case.profile), case.snr, case.seed) if case.unknown else None

    # --- what the profiles can tell apart (a property of the set, not of the workflow) -----------

    @cache  # noqa: B019
    def snr_space(self, pname: str) -> SnrSpace:
        nominal, prof = scenarios.nominal_model(), self.profile(pname)
        bins, builder, whitener = scenarios._snr_tools(nominal, prof, NoiseModel.of_model(nominal), MAX_BINS)
        base = scenarios.true_base(nominal)
        base_bins = bins.mean(builder.rate_dph(base))
        basis = gls_fit(builder, whitener, base_bins, base).basis

        def perp(binned: np.ndarray) -> np.ndarray:
            wc = whitener.white(binned)
            return wc - basis @ (basis.T @ wc)
        return SnrSpace(bins, builder, base, base_bins, perp)

    @cache  # noqa: B019
    def catalogue_columns(self, pname: str) -> dict[str, np.ndarray]:
        """Each deterministic sized catalogue effect's fitted columns in ``snr_space`` (orthonormal).

        periodic_interference is left out: it lives above the bins' band (its sizing
        is spectral), so its binned columns are nothing to compare.
        """
        space, columns = self.snr_space(pname), {}
        for name in self.profiles[pname].sized:
            if name == "periodic_interference":
                continue
            if name == "thermal_lag":
                lagged = space.base.with_effect(EffectSpec(name, {"tau_s": LAG_COLUMN_TAU_S}))
                cols = space.project_binned(space.bins.mean(space.builder.rate_dph(lagged))
                                            - space.base_bins)[:, None]
            else:
                spec = placeholder_spec(name, self.profiles[pname].shapes.get(name, {}))
                cols = space.project_binned(space.builder.extra_columns(space.base, spec)[1])
            q, r = np.linalg.qr(cols)
            columns[name] = q[:, np.abs(np.diag(r)) > 1e-9 * np.abs(r).max()]
        return columns

    def effect_signature(self, pname: str, name: str) -> np.ndarray:
        """The sized catalogue effect's 10σ signature in ``snr_space`` (norm ≈ 10)."""
        space = self.snr_space(pname)
        truth = space.base.with_effect(self.catalogue_spec(name, pname, 10.0))
        return space.project_binned(space.bins.mean(space.builder.rate_dph(truth)) - space.base_bins)

    def closest_catalogue(self, pname: str, signal: np.ndarray, leave_out: str = "") -> tuple[str, float]:
        """The single catalogue effect that explains most of ``signal`` and the SNR left after it.

        The SNR left is given at ``signal``'s own size: pass it sized (norm 10) or scale it.
        """
        left = {n: residual_snr(signal, c) for n, c in self.catalogue_columns(pname).items() if n != leave_out}
        name = min(left, key=left.get)
        return name, left[name]
