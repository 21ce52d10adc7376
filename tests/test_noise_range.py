"""The range of Gaussian noise over a window: the quantile a ripple band adds."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from spa.plan.settling import noise_range_quantile
from spa.plan.verify import promise_predictions


def test_two_samples_range_is_the_closed_form():
    # |z1 - z2| = sqrt(2) |z|: its q quantile is sqrt(2) times the normal's (1 + q) / 2
    for q, z in ((0.5, 0.6744897501960817), (0.95, 1.959963984540054), (0.99, 2.5758293035489)):
        assert noise_range_quantile(2, q) == pytest.approx(math.sqrt(2.0) * z, rel=1e-5)


@pytest.mark.parametrize("n", [10, 250, 1000, 4000])
def test_the_quantile_covers_as_stated_on_simulated_noise(n):
    rng = np.random.default_rng(n)
    z = rng.standard_normal((20000, n)).astype(np.float32)
    inside = float(np.mean(z.max(axis=1) - z.min(axis=1) <= noise_range_quantile(n)))
    # binomial sd at 20 000 windows is 0.0015: 4 sd either side
    assert abs(inside - 0.95) < 0.006


def test_it_grows_with_the_window_and_passes_the_old_fixed_multiple():
    qs = [noise_range_quantile(n) for n in (100, 300, 1000, 3000)]
    assert all(a < b for a, b in itertools.pairwise(qs))
    # 6.6 sd was exceeded by noise alone in 37 % of 1 000-sample windows
    assert noise_range_quantile(1000) > 7.0


def test_the_legacy_ripple_band_takes_the_window_quantile():
    bands = promise_predictions({"ripple_pp": 0.01}, 0.002, 0.001, samples=4000)
    assert bands["ripple_pp"]["hi"] == pytest.approx(
        0.01 + noise_range_quantile(4000) * 0.002 + 0.001
    )


@pytest.mark.parametrize("n,q", [(1, 0.95), (10, 0.0), (10, 1.0)])
def test_bad_arguments_are_named(n, q):
    with pytest.raises(ValueError, match="noise_range_quantile"):
        noise_range_quantile(n, q)
