"""Each pass of the discrepancy workflow on its own (issue 15: tests at the centre).

The workflow is ``_noise_pass`` → ``_search_pass`` → ``_gap_pass`` over one
shared ``_Search`` record; these tests run the passes one by one on a
simulated hour with a known hidden effect and check what each hands on.
"""

from __future__ import annotations

import discrepancy_scenarios as scenarios
import numpy as np
import pytest

from gyrocal.analysis.discrepancy.workflow import (
    _Analysis,
    _gap_pass,
    _noise_pass,
    _Search,
    _search_pass,
)

PROFILE = scenarios.procedure_profile(3600.0, 5.0)
pytestmark = pytest.mark.timeout(120)


@pytest.fixture(scope="module")
def setup():
    hidden = scenarios.sized_effect("temp_hysteresis", 15.0, PROFILE, max_bins=1000)
    log = scenarios.as_measured_log(scenarios.simulate_log(PROFILE, [hidden], 7))
    model = scenarios.nominal_model()
    return model, log, _Analysis(model, log, 7, 200, 1000)


def test_noise_pass_sets_the_noise_model_and_leaves_the_search_empty(setup) -> None:
    model, log, analysis = setup
    search = _Search(model, model)
    _noise_pass(analysis, log, search)
    assert search.noise is not None and search.noise_est is not None
    assert search.noise.arw_deg_per_rth > 0
    assert search.found == [] and search.current is model      # no lattice, no hump here
    assert any(n.startswith("noise model:") for n in search.notes)


def test_search_pass_names_the_hidden_effect_and_gap_pass_shows_the_gap_shrink(setup) -> None:
    model, log, analysis = setup
    search = _Search(model, model)
    _noise_pass(analysis, log, search)
    _search_pass(analysis, log, search, max_effects=3, progress=lambda _: None)
    assert [f.name for f in search.found][:1] == ["temp_hysteresis"]
    assert search.current.has_effect("temp_hysteresis")
    assert search.iterations and search.iterations[0].accepted == "temp_hysteresis"
    result = _gap_pass(analysis, log, search)
    gap = result.metrics["g1_segment_mean"]
    assert gap.after < gap.before
    assert not result.unexplained
    assert np.isfinite(result.metrics["allan_mismatch"].after)
