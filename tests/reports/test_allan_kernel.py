import numpy as np
import pytest

from gyrocal.analysis.allan import kernel as allan_kernel
from gyrocal.analysis.allan.deviation import overlapping_adev


def test_numba_is_installed_so_the_fast_path_is_what_runs():
    assert allan_kernel.AVAILABLE


@pytest.mark.parametrize("kind", ["white", "random_walk"])
def test_compiled_kernel_equals_the_numpy_path(kind):
    rng = np.random.default_rng(7)
    y = rng.standard_normal(50_000)
    if kind == "random_walk":
        y = np.cumsum(y) * 1e-3 + 5.0
    fast = overlapping_adev(y, 200.0, confidence=None)
    slow = overlapping_adev(y, 200.0, confidence=None, compiled=False)
    np.testing.assert_array_equal(fast.tau_s, slow.tau_s)
    np.testing.assert_allclose(fast.adev, slow.adev, rtol=1e-12, atol=0)
