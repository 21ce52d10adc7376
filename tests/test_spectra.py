"""Bicoherence against phase-coupled signals, Gaussian noise, the literal double loop and its own
conventions, in both normalisations (bounded, the default; HOSA's)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from spa.openloop.spectra import (
    bicoherence,
    mean_bicoherence,
    principal_domain_mask,
    segment_count,
    significance_threshold,
    significant_fraction,
)


def bicoher_loop(x, fs, nfft, overlap, normalisation="hosa"):
    """HOSA ``bicoher`` written out literally: a loop over segments, then over (f1, f2).

    ``normalisation="bounded"`` divides instead by ``<|Y1 Y2|^2> <|Y3|^2>`` (Kim & Powers).
    """
    n = nfft
    noverlap = math.floor(n * overlap + 1e-9)
    advance = n - noverlap
    n_seg = (len(x) - noverlap) // advance
    w = 0.5 * (1 - np.cos(2 * np.pi * np.arange(1, n + 1) / (n + 1)))  # MATLAB hanning(n)
    Y = np.empty((n_seg, n), dtype=complex)
    for k in range(n_seg):
        s = np.asarray(x[k * advance : k * advance + n], dtype=float)
        Y[k] = np.fft.fft((s - s.mean()) * w) / n
    P = np.mean(np.abs(Y) ** 2, axis=0)
    bic = np.empty((n, n))
    with np.errstate(invalid="ignore", divide="ignore"):  # 0/0 -> NaN, as in MATLAB
        for i in range(n):
            for j in range(n):
                m = (i + j) % n
                b = np.mean(Y[:, i] * Y[:, j] * np.conj(Y[:, m]))
                if normalisation == "hosa":
                    bic[i, j] = abs(b) ** 2 / (P[i] * P[j] * P[m])
                else:
                    bic[i, j] = abs(b) ** 2 / (np.mean(np.abs(Y[:, i] * Y[:, j]) ** 2) * P[m])
    return np.fft.fftshift(np.fft.fftfreq(n, d=1 / fs)), np.fft.fftshift(bic), P


def three_tones(coupled, n_seg=128, nfft=64, fs=1000.0, seed=0):
    """Tones at bins 8, 16 and 24 with fresh phases in every (non-overlapping) segment.

    Coupled: the third phase is the sum of the first two; otherwise it is independent.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(n_seg * nfft) / fs
    seg = np.repeat(np.arange(n_seg), nfft)
    ph1, ph2, ph_free = rng.uniform(0, 2 * np.pi, (3, n_seg))
    ph3 = ph1 + ph2 if coupled else ph_free
    df = fs / nfft
    f1, f2 = 8 * df, 16 * df
    x = (
        np.cos(2 * np.pi * f1 * t + ph1[seg])
        + np.cos(2 * np.pi * f2 * t + ph2[seg])
        + np.cos(2 * np.pi * (f1 + f2) * t + ph3[seg])
        + 0.1 * rng.standard_normal(t.size)
    )
    return x, fs, nfft, f1, f2


def test_quadratic_phase_coupling_gives_a_peak_at_f1_f2():
    x, fs, nfft, f1, f2 = three_tones(coupled=True)
    f, bic = bicoherence(x, fs, nfft=nfft, overlap=0.0)
    mask = principal_domain_mask(f)
    i, j = np.searchsorted(f, [f2, f1])  # principal domain: first frequency >= second
    assert mask[i, j]
    assert bic[i, j] > 0.95
    # The Hann window's main lobe spreads each tone over +-1 bin, and the leaked components
    # keep the phase coupling: the peak is 3 x 3 bins wide. Everything else is low.
    others = np.where(mask, bic, 0.0)
    others[i - 1 : i + 2, j - 1 : j + 2] = 0.0
    assert others.max() < 0.2
    assert np.median(bic[mask]) < 0.02
    # symmetric in (f1, f2)
    np.testing.assert_allclose(bic, bic.T, rtol=1e-12, atol=1e-15)


def test_independent_phases_give_no_peak():
    x, fs, nfft, f1, f2 = three_tones(coupled=False)
    f, bic = bicoherence(x, fs, nfft=nfft, overlap=0.0)
    i, j = np.searchsorted(f, [f2, f1])
    assert bic[i, j] < 0.1
    assert bic[principal_domain_mask(f)].max() < 0.2


def test_coupled_ranks_above_independent():
    f, coupled = bicoherence(*three_tones(coupled=True)[:3], overlap=0.0)
    _, free = bicoherence(*three_tones(coupled=False)[:3], overlap=0.0)
    assert mean_bicoherence(f, coupled) > mean_bicoherence(f, free)


@pytest.mark.parametrize(
    ("nfft", "overlap", "length"),
    [(16, 0.5, 300), (15, 0.3, 211), (8, 0.0, 64), (32, 0.75, 500), (2, 0.0, 9)],
)
@pytest.mark.parametrize("normalisation", ["bounded", "hosa"])
def test_equals_the_literal_double_loop(nfft, overlap, length, normalisation):
    rng = np.random.default_rng(nfft)
    x = rng.standard_normal(length).cumsum() ** 2  # non-Gaussian, with a trend
    f, bic = bicoherence(x, 250.0, nfft=nfft, overlap=overlap, normalisation=normalisation)
    f_ref, bic_ref, _ = bicoher_loop(x, 250.0, nfft, overlap, normalisation)
    np.testing.assert_array_equal(f, f_ref)
    np.testing.assert_allclose(bic, bic_ref, rtol=0, atol=1e-10)


@settings(max_examples=25, deadline=None)
@given(
    x=arrays(np.float64, st.integers(12, 80), elements=st.floats(-10, 10)),
    nfft=st.integers(2, 12),
    overlap=st.sampled_from([0.0, 0.25, 0.5, 0.9]),
)
def test_equals_the_literal_double_loop_property(x, nfft, overlap):
    assume(nfft <= len(x) and segment_count(len(x), nfft, overlap) >= 2)
    _, bic = bicoherence(x, 1.0, nfft=nfft, overlap=overlap, normalisation="hosa")
    _, bic_ref, power = bicoher_loop(x, 1.0, nfft, overlap)
    # Not comparable: bins with no power (0/0, reported as 0 by spa) or only rounding error
    # (e.g. a constant x minus its computed mean), where the ratio is noise in both versions.
    assume(power.min() > 1e-20 * max(1.0, float(np.max(x**2))))
    scale = max(1.0, float(np.max(bic_ref)))
    np.testing.assert_allclose(bic, bic_ref, rtol=1e-8, atol=1e-10 * scale)


@pytest.mark.parametrize("normalisation", ["bounded", "hosa"])
def test_invariant_to_gain_and_offset(normalisation):
    x = np.random.default_rng(3).standard_normal(2000) ** 2
    _, a = bicoherence(x, 100.0, nfft=32, normalisation=normalisation)
    _, b = bicoherence(-3.5 * x + 12.0, 100.0, nfft=32, normalisation=normalisation)
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)


# ---- the bounded normalisation and its significance ------------------------------------


@settings(max_examples=40, deadline=None)
@given(
    x=arrays(np.float64, st.integers(16, 120), elements=st.floats(-1e3, 1e3)),
    nfft=st.integers(2, 16),
    overlap=st.sampled_from([0.0, 0.5, 0.75]),
)
def test_bounded_bicoherence_lies_in_zero_one(x, nfft, overlap):
    assume(nfft <= len(x) and segment_count(len(x), nfft, overlap) >= 2)
    _, bic = bicoherence(x, 1.0, nfft=nfft, overlap=overlap)
    assert np.all(np.isfinite(bic)) and bic.min() >= 0.0 and bic.max() <= 1.0


def test_bounded_is_one_for_quadratic_phase_coupling_where_hosa_may_exceed_it():
    x, fs, nfft, f1, f2 = three_tones(coupled=True, n_seg=64)
    f, bounded = bicoherence(x, fs, nfft=nfft, overlap=0.0)
    i, j = np.searchsorted(f, [f2, f1])
    assert bounded[i, j] > 0.99  # |<Y1 Y2 Y3*>|^2 = <|Y1 Y2|^2><|Y3|^2> for locked phases
    # A quadratic product of components whose common amplitude a changes from segment to
    # segment: tones a, a and a^2. HOSA's ratio is then <a^4>/<a^2>^2 > 1 at the coupled bin;
    # the bounded one stays at 1 (Cauchy-Schwarz with equality: |Y1 Y2| ~ |Y3|).
    rng = np.random.default_rng(5)
    n_seg = 64
    t = np.arange(n_seg * nfft) / fs
    seg = np.repeat(np.arange(n_seg), nfft)
    a = rng.uniform(0.2, 3.0, n_seg)[seg]
    ph1, ph2 = rng.uniform(0, 2 * np.pi, (2, n_seg))
    y = (
        a * np.cos(2 * np.pi * f1 * t + ph1[seg])
        + a * np.cos(2 * np.pi * f2 * t + ph2[seg])
        + a**2 * np.cos(2 * np.pi * (f1 + f2) * t + ph1[seg] + ph2[seg])
    )
    _, hosa = bicoherence(y, fs, nfft=nfft, overlap=0.0, normalisation="hosa")
    _, kim = bicoherence(y, fs, nfft=nfft, overlap=0.0)
    assert hosa[i, j] > 1.3 and 0.99 < kim[i, j] <= 1.0


def test_gaussian_noise_is_significant_in_about_alpha_of_the_domain():
    rng = np.random.default_rng(11)
    nfft, alpha = 64, 0.01
    fractions = []
    for _ in range(4):
        x = rng.standard_normal(nfft * 200)  # 200 independent segments
        f, bic = bicoherence(x, 1.0, nfft=nfft, overlap=0.0)
        threshold = significance_threshold(200, alpha)
        fractions.append(significant_fraction(f, bic, threshold, fmin=2 / nfft))
    # 4 x ~500 bins: the false-alarm rate is alpha within its binomial spread
    assert 0.003 < np.mean(fractions) < 0.02


def test_significance_threshold_is_the_beta_tail():
    # P(b2 > x) = (1 - x)**(K - 1): at the threshold it is alpha
    for k, alpha in ((2, 0.5), (38, 0.01), (116, 0.01), (467, 0.05)):
        x = significance_threshold(k, alpha)
        assert (1 - x) ** (k - 1) == pytest.approx(alpha, rel=1e-12)
    with pytest.raises(ValueError, match="n_segments"):
        significance_threshold(1)
    with pytest.raises(ValueError, match="alpha"):
        significance_threshold(10, alpha=1.0)


def test_unknown_normalisation_is_refused():
    with pytest.raises(ValueError, match="normalisation"):
        bicoherence(np.ones(64), 1.0, nfft=16, normalisation="kim")


def test_segment_count_and_frequency_axis():
    # 100 samples, nfft 16, 50 %: advance 8, floor((100 - 8)/8) = 11 segments; a signal that is
    # non-zero only in the last 4 samples lies in no segment: every bin has zero power.
    x = np.zeros(100)
    x[-4:] = [1.0, -2.0, 3.0, 0.5]
    f, bic = bicoherence(x, 8.0, nfft=16, overlap=0.5)
    np.testing.assert_array_equal(f, np.arange(-8, 8) * 0.5)
    assert np.all(bic == 0.0)  # 0/0 is reported as 0


def test_constant_signal_gives_zeros_without_warnings():
    _, bic = bicoherence(np.full(64, 2.0), 1.0, nfft=16)
    assert bic.shape == (16, 16) and np.all(bic == 0.0)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"x": np.ones(10), "nfft": 11}, "nfft"),
        ({"x": np.ones(10), "nfft": 1}, "nfft"),
        ({"x": np.ones(10), "nfft": 4.5}, "nfft"),
        ({"x": np.ones(10), "nfft": 4, "overlap": 1.0}, "overlap"),
        ({"x": np.ones(10), "nfft": 4, "overlap": -0.1}, "overlap"),
        ({"x": np.ones(10), "nfft": 4, "overlap": float("nan")}, "overlap"),
        ({"x": np.r_[np.ones(9), np.nan], "nfft": 4}, "x"),
        ({"x": np.r_[np.ones(9), np.inf], "nfft": 4}, "x"),
        ({"x": np.ones((2, 10)), "nfft": 4}, "x"),
        ({"x": np.ones(10) * 1j, "nfft": 4}, "x"),
        ({"x": np.ones(10), "nfft": 4, "fs": 0.0}, "fs"),
    ],
)
def test_bad_input_names_the_argument(kwargs, name):
    kwargs = {"fs": 1.0, **kwargs}
    with pytest.raises(ValueError, match=name):
        bicoherence(**kwargs)


def test_principal_domain_is_the_inner_triangle():
    for n in (8, 9, 64):
        f = np.fft.fftshift(np.fft.fftfreq(n, d=0.01))
        fs = 100.0
        m = principal_domain_mask(f)
        f1, f2 = np.meshgrid(f, f, indexing="ij")
        tol = 1e-9
        expected = (f2 >= -tol) & (f2 <= f1 + tol) & (f1 + f2 <= fs / 2 + tol)
        np.testing.assert_array_equal(m, expected)
    # fmin of one bin drops the f2 = 0 row
    f = np.fft.fftshift(np.fft.fftfreq(8, d=1 / 8.0))
    m = principal_domain_mask(f, fmin=1.0)
    assert not m[:, f == 0].any() and m.sum() == 4


def test_bad_axis_or_map_names_the_argument():
    f = np.fft.fftshift(np.fft.fftfreq(8))
    with pytest.raises(ValueError, match="f must"):
        principal_domain_mask(np.linspace(0, 1, 8))
    with pytest.raises(ValueError, match="fmin"):
        principal_domain_mask(f, fmin=-1.0)
    with pytest.raises(ValueError, match="bic"):
        mean_bicoherence(f, np.zeros((7, 7)))
    with pytest.raises(ValueError, match="bic"):
        mean_bicoherence(f, np.full((8, 8), np.nan))
    with pytest.raises(ValueError, match="fmin"):
        mean_bicoherence(f, np.zeros((8, 8)), fmin=10.0)


def test_a_single_segment_is_refused_not_answered_with_ones():
    """One segment makes |B|^2 equal P1*P2*P12 everywhere: the "bicoherence" would be 1."""
    x = np.random.default_rng(0).normal(size=256)
    with pytest.raises(ValueError, match="1 segment of nfft = 256"):
        bicoherence(x, 1000.0, nfft=256)
    f, b = bicoherence(x, 1000.0, nfft=128)  # three half-overlapping segments
    assert b.shape == (f.size, f.size)
