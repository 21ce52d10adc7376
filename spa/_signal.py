"""The few signal-processing routines spa uses, without importing :mod:`scipy.signal`.

``import scipy.signal`` loads :mod:`scipy.stats` and :mod:`scipy.interpolate` with it (about
a second of every workflow job, ``benchmarks/README.md``, "A dataset's analysis"), while spa
needs six of its functions. They are written here in the same arithmetic as SciPy 1.17's
(same least-squares driver, same FFT sizes, the same convolution routine), so that their
results are the same to the last bit;
``tests/test_signal.py`` compares each with :mod:`scipy.signal`. They use :mod:`scipy.fft`,
:mod:`scipy.linalg` and :mod:`scipy.ndimage`, imported when first called.
"""

from __future__ import annotations

import math
from itertools import accumulate

import numpy as np
import numpy.typing as npt

__all__ = [
    "correlate",
    "correlation_lags",
    "decimate",
    "fftconvolve",
    "first_order_filter",
    "savgol_coeffs",
    "savgol_filter",
]

Array = npt.NDArray[np.float64]


def _lstsq(a: Array, b: Array, rcond: float | None = None) -> tuple[Array, int]:
    """Least squares as :mod:`scipy.signal` solves them (LAPACK ``gelsd``): solution, rank."""
    from scipy.linalg import lstsq

    if rcond is None:
        rcond = np.finfo(a.dtype).eps * max(a.shape[-1], a.shape[-2])
    solution, _, rank, _ = lstsq(a, b, cond=rcond)
    return solution, int(rank)


def savgol_coeffs(window_length: int, polyorder: int, deriv: int = 0, delta: float = 1.0) -> Array:
    """Savitzky–Golay convolution coefficients (``scipy.signal.savgol_coeffs``, ``use="conv"``).

    Parameters
    ----------
    window_length : int
        Number of taps, > ``polyorder``.
    polyorder : int
        Order of the fitted polynomial.
    deriv : int, default 0
        Order of the derivative the filter returns.
    delta : float, default 1.0
        Sample spacing (the derivative's time unit).

    Returns
    -------
    numpy.ndarray, shape (window_length,)
        Coefficients for a convolution: the least-squares polynomial through the window,
        evaluated (or differentiated ``deriv`` times) at its centre.

    Raises
    ------
    ValueError
        If ``polyorder >= window_length``.

    Notes
    -----
    The design matrix holds the powers ``0..polyorder`` of the sample offsets from the
    window's centre, reversed for convolution; the coefficients solve ``A c = e_deriv *
    deriv!/delta**deriv`` in the least-squares sense, as SciPy does.

    Examples
    --------
    >>> savgol_coeffs(5, 2).round(6)
    array([-0.085714,  0.342857,  0.485714,  0.342857, -0.085714])
    """
    if polyorder >= window_length:
        raise ValueError("polyorder must be less than window_length.")
    half, rem = divmod(window_length, 2)
    pos = half if rem else half - 0.5
    if deriv > polyorder:
        return np.zeros(window_length)
    x = np.arange(-pos, window_length - pos, dtype=np.float64)[::-1]
    order = np.arange(polyorder + 1, dtype=np.float64).reshape(-1, 1)
    design = x**order
    y = np.zeros(polyorder + 1)
    y[deriv] = math.factorial(deriv) / (delta**deriv)
    return _lstsq(design, y)[0]


def _polyfit(x: Array, y: Array, deg: int) -> Array:
    """``scipy.signal._polyutils.polyfit``: columns of ``y`` fitted on ``x`` (highest first)."""
    powers = np.arange(deg + 1, dtype=x.dtype)[::-1]
    lhs = x[:, None] ** powers[None, :]
    scale = np.sqrt(np.sum(lhs * lhs, axis=0))
    lhs /= scale
    c, _ = _lstsq(lhs, y, rcond=x.shape[0] * np.finfo(x.dtype).eps)
    return (c.T / scale).T


def _polyder(p: Array, m: int) -> Array:
    """``m``-th derivative of the polynomials in the columns of ``p`` (highest power first)."""
    if m == 0:
        return p
    n = p.shape[0]
    if n <= m:
        return np.zeros_like(p[:1, ...])
    dp = np.array(p[:-m, ...], copy=True)
    for k in range(m):
        rng = np.arange(n - k - 1, m - k - 1, -1, dtype=p.dtype)
        dp *= rng.reshape((n - m,) + (1,) * (p.ndim - 1))
    return dp


def _fit_edge(x: Array, start: int, stop: int, lo: int, hi: int, order: int, deriv: int,
              delta: float, y: Array) -> None:  # fmt: skip
    """Replace ``y[..., lo:hi]`` by the polynomial fitted to ``x[..., start:stop]``."""
    edge = np.moveaxis(x[..., start:stop], -1, 0)
    shape = edge.shape
    coeffs = _polyder(_polyfit(np.arange(0, stop - start, dtype=x.dtype),
                               edge.reshape(shape[0], -1), order), deriv)  # fmt: skip
    i = np.arange(lo - start, hi - start, dtype=coeffs.dtype).reshape(-1, 1)
    values = np.zeros_like(i)
    for j in range(coeffs.shape[0]):
        values = values * i + coeffs[j, ...]
    values = values / (delta**deriv)
    y[..., lo:hi] = np.moveaxis(values.reshape((hi - lo, *shape[1:])), 0, -1)


def savgol_filter(
    x: npt.ArrayLike, window_length: int, polyorder: int, deriv: int = 0, delta: float = 1.0
) -> Array:
    """Savitzky–Golay filter along the last axis (``scipy.signal.savgol_filter``, ``"interp"``).

    Parameters
    ----------
    x : array_like of float
        Signal(s), filtered along the last axis.
    window_length, polyorder, deriv, delta
        As :func:`savgol_coeffs`.

    Returns
    -------
    numpy.ndarray of float64
        The filtered signal; within ``window_length // 2`` samples of each end, the
        polynomial fitted to the first (last) ``window_length`` samples, evaluated there.

    Raises
    ------
    ValueError
        If ``window_length`` exceeds the signal's length.

    Examples
    --------
    >>> savgol_filter(np.arange(7.0) ** 2, 5, 2).round(12)
    array([ 0.,  1.,  4.,  9., 16., 25., 36.])
    """
    from scipy.ndimage import convolve1d

    data = np.asarray(x)
    if data.dtype != np.float64 and data.dtype != np.float32:
        data = data.astype(np.float64)
    coeffs = savgol_coeffs(window_length, polyorder, deriv=deriv, delta=delta)
    n = data.shape[-1]
    if window_length > n:
        raise ValueError(
            "If mode is 'interp', window_length must be less than or equal to the size of x."
        )
    y = convolve1d(data, coeffs, axis=-1, mode="constant")
    half = window_length // 2
    _fit_edge(data, 0, window_length, 0, half, polyorder, deriv, delta, y)
    _fit_edge(data, n - window_length, n, n - half, n, polyorder, deriv, delta, y)
    return y


def fftconvolve(
    in1: npt.ArrayLike, in2: npt.ArrayLike, mode: str = "full", axes: int | None = None
) -> Array:
    """Convolution of two real arrays by FFT (``scipy.signal.fftconvolve``).

    Parameters
    ----------
    in1, in2 : array_like of float
        Arrays of one number of dimensions; along the axes not convolved their lengths are
        equal or 1 (broadcast).
    mode : {"full", "valid"}, default "full"
        ``"valid"``: only the outputs where ``in2`` lies within ``in1`` (``in1`` at least
        as long as ``in2`` along the convolved axes).
    axes : int, optional
        The one axis to convolve along; all axes when omitted.

    Returns
    -------
    numpy.ndarray of float64
        The convolution.

    Raises
    ------
    ValueError
        If the arrays differ in dimensions, ``mode`` is unknown, or ``in1`` is shorter than
        ``in2`` in ``"valid"`` mode.

    Examples
    --------
    >>> fftconvolve([1.0, 2.0, 3.0], [0.0, 1.0, 0.5]).round(12) + 0.0
    array([0. , 1. , 2.5, 4. , 1.5])
    """
    from scipy import fft as sp_fft

    a = np.asarray(in1, dtype=np.float64)
    b = np.asarray(in2, dtype=np.float64)
    if a.ndim != b.ndim:
        raise ValueError("in1 and in2 should have the same dimensionality")
    if mode not in ("full", "valid"):
        raise ValueError("acceptable mode flags are 'valid' or 'full'")
    chosen = list(range(a.ndim)) if axes is None else [axes % a.ndim]
    chosen = [i for i in chosen if a.shape[i] != 1 and b.shape[i] != 1]
    if mode == "valid" and any(a.shape[i] < b.shape[i] for i in chosen):
        raise ValueError("in1 must be at least as long as in2 in 'valid' mode")
    shape = [a.shape[i] + b.shape[i] - 1 if i in chosen else max(a.shape[i], b.shape[i])
             for i in range(a.ndim)]  # fmt: skip
    if not chosen:
        ret = a * b
    else:
        fshape = [sp_fft.next_fast_len(shape[i], True) for i in chosen]
        spectrum = sp_fft.rfftn(a, fshape, axes=chosen) * sp_fft.rfftn(b, fshape, axes=chosen)
        ret = sp_fft.irfftn(spectrum, fshape, axes=chosen)[tuple(slice(n) for n in shape)]
    if mode == "full":
        return ret.copy()
    valid = [a.shape[i] - b.shape[i] + 1 if i in chosen else ret.shape[i] for i in range(a.ndim)]
    start = [(c - v) // 2 for c, v in zip(ret.shape, valid, strict=True)]
    return ret[tuple(slice(s, s + v) for s, v in zip(start, valid, strict=True))].copy()


def correlate(in1: npt.ArrayLike, in2: npt.ArrayLike) -> Array:
    """Full cross-correlation of two real 1-D signals by FFT.

    ``scipy.signal.correlate(in1, in2, mode="full", method="fft")``: ``out[i] = sum_k
    in1[k + lags[i]] * in2[k]`` with ``lags`` from :func:`correlation_lags`.

    Parameters
    ----------
    in1, in2 : array_like of float, shape (n1,), (n2,)
        The signals.

    Returns
    -------
    numpy.ndarray of float64, shape (n1 + n2 - 1,)
        The correlation at every lag.

    Examples
    --------
    >>> correlate([0.0, 1.0, 0.0], [1.0, 0.0, 0.0]).round(12) + 0.0
    array([0., 0., 0., 1., 0.])
    """
    return fftconvolve(in1, np.asarray(in2, dtype=np.float64)[::-1], mode="full")


def correlation_lags(n1: int, n2: int) -> npt.NDArray[np.int_]:
    """Lags of :func:`correlate`'s outputs (``scipy.signal.correlation_lags``, ``mode="full"``).

    Examples
    --------
    >>> correlation_lags(3, 2)
    array([-1,  0,  1,  2])
    """
    return np.arange(-n2 + 1, n1)


def first_order_filter(drive: npt.ArrayLike, a: float, y0: float) -> Array:
    """``y[k] = a*y[k-1] + drive[k]`` with ``y[-1]`` such that ``y[0] = y0 + drive[0]``.

    ``scipy.signal.lfilter([1], [1, -a], drive, zi=[y0])[0]``, in the same floating-point
    operations (so the same bits): a sequential recursion, run by :func:`itertools.accumulate`.

    Parameters
    ----------
    drive : array_like of float, shape (n,)
        The input.
    a : float
        The pole.
    y0 : float
        The filter's initial state.

    Returns
    -------
    numpy.ndarray of float64, shape (n,)
        The output.

    Examples
    --------
    >>> first_order_filter([0.0, 1.0, 1.0], 0.5, 2.0)
    array([2., 2., 2.])
    """
    x = np.asarray(drive, dtype=np.float64).tolist()
    if not x:
        return np.zeros(0)
    pole = float(a)
    first = float(y0) + x[0]
    return np.fromiter(
        accumulate(x[1:], lambda y, xk: pole * y + xk, initial=first),
        dtype=np.float64,
        count=len(x),
    )


def _firwin_lowpass(numtaps: int, cutoff: float) -> Array:
    """``scipy.signal.firwin(numtaps, cutoff)``: Hamming-windowed sinc, unit gain at DC."""
    m = np.arange(0, numtaps, dtype=np.float64) - 0.5 * (numtaps - 1)
    h = cutoff * np.sinc(cutoff * m) - 0.0 * np.sinc(0.0 * m)
    fac = np.linspace(-np.pi, np.pi, numtaps, dtype=np.float64)
    window = np.zeros(numtaps)
    for k, weight in enumerate((0.54, 1.0 - 0.54)):
        window += weight * np.cos(k * fac)
    h *= window
    return h / np.sum(h * np.cos(np.pi * m * 0.0))


def decimate(x: npt.ArrayLike, q: int) -> Array:
    """Downsample by ``q`` after a zero-phase anti-aliasing FIR filter.

    ``scipy.signal.decimate(x, q, ftype="fir", zero_phase=True)``: a Hamming-windowed sinc
    of ``20 q + 1`` taps, cut-off at ``1/q`` of Nyquist, centred on every ``q``-th sample,
    with zeros beyond the ends.

    Parameters
    ----------
    x : array_like of float, shape (n,)
        The signal.
    q : int
        Downsampling factor, >= 1.

    Returns
    -------
    numpy.ndarray of float64, shape (ceil(n / q),)
        The filtered signal at samples ``0, q, 2q, ...``.

    Raises
    ------
    ValueError
        If ``q < 1``.

    Notes
    -----
    The sums are added as SciPy's polyphase routine (``upfirdn``) adds them, oldest sample
    first, so the result is the same to the last bit.

    Examples
    --------
    >>> decimate(np.ones(200), 4)[20:30].round(6)  # away from the ends: DC passes
    array([1., 1., 1., 1., 1., 1., 1., 1., 1., 1.])
    """
    q = int(q)
    if q < 1:
        raise ValueError(f"q must be >= 1, got {q}")
    data = np.asarray(x, dtype=np.float64)
    if q == 1:
        return data.copy()
    half = 10 * q
    h = _firwin_lowpass(2 * half + 1, 1.0 / q)
    n_out = -(-data.size // q)
    padded = np.concatenate((np.zeros(2 * half), data, np.zeros(2 * half)))
    centre = np.arange(n_out) * q + 3 * half  # x[i q + half] in ``padded``
    out = np.zeros(n_out)
    for k in range(2 * half, -1, -1):  # y[i] = sum_k h[k] x[i q + half - k], oldest first
        out += padded[centre - k] * h[k]
    return out
