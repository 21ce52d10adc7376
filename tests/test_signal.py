"""spa._signal against scipy.signal: the same numbers without importing scipy.signal."""

import subprocess
import sys

import numpy as np
import pytest
from scipy import signal

from spa import _signal


@pytest.fixture
def noisy():
    rng = np.random.default_rng(7)
    t = np.arange(0, 3.0, 1e-3)
    return 0.8 * (1 - np.exp(-t / 0.4)) + 1e-3 * rng.standard_normal(t.size)


@pytest.mark.parametrize(
    "w, order, deriv", [(5, 2, 0), (31, 3, 1), (30, 2, 1), (11, 4, 2), (7, 2, 3)]
)
def test_savgol_coeffs_bit_identical(w, order, deriv):
    ours = _signal.savgol_coeffs(w, order, deriv=deriv, delta=1e-3)
    ref = signal.savgol_coeffs(w, order, deriv=deriv, delta=1e-3, use="conv")
    assert np.array_equal(ours, ref)


@pytest.mark.parametrize("w, order, deriv", [(31, 3, 0), (31, 3, 1), (51, 2, 1), (8, 2, 0)])
def test_savgol_filter_bit_identical(noisy, w, order, deriv):
    rows = np.vstack([noisy, noisy[::-1], 2 * noisy])
    for x in (noisy, rows):
        ours = _signal.savgol_filter(x, w, order, deriv=deriv, delta=1e-3)
        ref = signal.savgol_filter(x, w, order, deriv=deriv, delta=1e-3, axis=-1, mode="interp")
        assert np.array_equal(ours, ref)


def test_savgol_filter_rejects_a_long_window():
    with pytest.raises(ValueError, match="window_length"):
        _signal.savgol_filter(np.ones(4), 5, 2)


def test_fftconvolve_bit_identical(noisy):
    k = _signal.savgol_coeffs(31, 3, deriv=1, delta=1e-3)[None, :]
    rows = np.vstack([noisy[:900], noisy[1000:1900]])
    assert np.array_equal(
        _signal.fftconvolve(rows, k, mode="valid", axes=1),
        signal.fftconvolve(rows, k, mode="valid", axes=1),
    )
    assert np.array_equal(
        _signal.fftconvolve(noisy, noisy[:77]), signal.fftconvolve(noisy, noisy[:77])
    )


def test_correlate_bit_identical(noisy):
    a, b = noisy - noisy.mean(), np.sin(np.arange(noisy.size) * 0.01)
    assert np.array_equal(
        _signal.correlate(a, b), signal.correlate(a, b, mode="full", method="fft")
    )
    assert np.array_equal(
        _signal.correlation_lags(a.size, 17), signal.correlation_lags(a.size, 17, mode="full")
    )


def test_first_order_filter_bit_identical(noisy):
    a = float(np.exp(-1e-3 / 0.3))
    drive = np.concatenate(([0.0], (1 - a) * 1.2 * noisy[:-1]))
    ref, _ = signal.lfilter([1.0], [1.0, -a], drive, zi=[0.37])
    assert np.array_equal(_signal.first_order_filter(drive, a, 0.37), ref)
    assert _signal.first_order_filter([], a, 0.0).size == 0


@pytest.mark.parametrize("q, n", [(2, 1000), (4, 2999), (5, 2998), (1, 10)])
def test_decimate_bit_identical(noisy, q, n):
    x = noisy[:n] + np.sin(np.arange(n) * 0.7)  # content above the cut-off, to be removed
    ours = _signal.decimate(x, q)
    ref = x.copy() if q == 1 else signal.decimate(x, q, ftype="fir", zero_phase=True)
    assert ours.shape == ref.shape and np.array_equal(ours, ref)


def test_decimate_rejects_q_below_one():
    with pytest.raises(ValueError, match="q must be"):
        _signal.decimate(np.ones(5), 0)


def test_the_analysis_stages_do_not_import_scipy_signal():
    code = (
        "import sys, spa.stages.identify, spa.stages.tune, spa.stages.staircase, "
        "spa.stages.sine, spa.stages.chirp, spa.openloop, spa.identification.rates, "
        "spa.identification.rate_fits, spa.openloop.chirp, spa.openloop.sine_fit, "
        "spa.openloop.reference\n"
        "print(sorted(m for m in ('scipy.signal', 'scipy.stats') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
