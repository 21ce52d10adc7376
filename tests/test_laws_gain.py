"""The laws' choice rule on few runs: a t-test whose level does not depend on the runs'
number (spa.identification.laws_fit.gain_quantile)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.stats import norm

from spa.identification.laws_fit import GAIN_LEVEL, gain_quantile


def test_the_level_is_two_normal_standard_errors():
    assert GAIN_LEVEL == pytest.approx(norm.cdf(2.0), abs=1e-12)
    # with many runs the t quantile goes to the normal's 2
    assert gain_quantile(10_000) == pytest.approx(2.0, abs=2e-3)


@pytest.mark.parametrize("n", [2, 3, 6, 10])
def test_no_true_gain_passes_at_the_stated_rate_whatever_the_runs(n):
    rng = np.random.default_rng(58 + n)
    d = rng.normal(0.0, 3.0, size=(200_000, n))
    z = d.mean(axis=1) / (d.std(axis=1, ddof=1) / math.sqrt(n))
    rate = float(np.mean(z > gain_quantile(n)))
    assert rate == pytest.approx(1.0 - GAIN_LEVEL, abs=0.0015)
    # a fixed 2 standard errors passes far more often on few runs: 14.8 % at n = 2
    if n == 2:
        assert float(np.mean(z > 2.0)) == pytest.approx(0.1476, abs=0.004)


def test_the_quantile_falls_with_the_runs():
    q = [gain_quantile(n) for n in range(2, 30)]
    assert all(a > b for a, b in itertools.pairwise(q))


@pytest.mark.parametrize("n", [1, 0, -3])
def test_too_few_runs_are_named(n):
    with pytest.raises(ValueError, match="gain_quantile: n = "):
        gain_quantile(n)
