"""Each pass of the discrepancy workflow on its own (issue 15: tests at the centre).

The workflow is ``_noise_pass`` → ``_search_pass`` → ``_gap_pass``, each
returning what the next needs (issue 27: no shared search record); these tests
run the passes one by one on a simulated hour with a known hidden effect and
check what each hands on.
"""

from __future__ import annotations

import discrepancy_scenarios as scenarios
import numpy as np
import pytest

from gyrocal.analysis.discrepancy.context import Context
from gyrocal.analysis.discrepancy.workflow import _gap_pass, _noise_pass, _search_pass

PROFILE = scenarios.procedure_profile(3600.0, 5.0)
pytestmark = pytest.mark.timeout(120)


@pytest.fixture(scope="module")
def setup():
    hidden = scenarios.sized_effect("temp_hysteresis", 15.0, PROFILE, max_bins=1000)
    log = scenarios.as_measured_log(scenarios.simulate_log(PROFILE, [hidden], 7))
    model = scenarios.nominal_model()
    return model, log, Context(model, log, 7, 200, 1000)


def test_noise_pass_sets_the_noise_model_and_leaves_the_search_empty(setup) -> None:
    model, _log, ctx = setup
    noise = _noise_pass(ctx, model)
    assert noise.state.noise.arw_deg_per_rth > 0 and noise.estimate is not None
    assert noise.before == noise.state.noise        # no lattice: nothing added to the noise
    assert noise.state.found == () and noise.state.current is model      # no lattice, no hump here
    assert any(n.startswith("noise model:") for n in noise.state.notes)


def test_search_pass_names_the_hidden_effect_and_gap_pass_shows_the_gap_shrink(setup) -> None:
    model, _log, ctx = setup
    noise = _noise_pass(ctx, model)
    search = _search_pass(ctx, noise.state, max_effects=3, progress=lambda _: None)
    assert [f.name for f in search.state.found][:1] == ["temp_hysteresis"]
    assert search.state.current.has_effect("temp_hysteresis")
    assert search.iterations and search.iterations[0].accepted == "temp_hysteresis"
    assert search.preempted is None and search.nonstationary is None
    assert noise.state.found == ()                  # the pass returned a new state, the old one is intact
    result = _gap_pass(ctx, model, noise, search)
    gap = result.metrics["g1_segment_mean"]
    assert gap.after < gap.before
    assert not result.unexplained
    # the named effect's own gap comes from its kind in the registry and heads the story
    assert result.primary == result.effect_gaps["temp_hysteresis"] == "temp_hysteresis_pattern_dph"
    assert np.isfinite(result.metrics["allan_mismatch"].after)
