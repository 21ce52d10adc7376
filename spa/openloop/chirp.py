"""One chirp run: the bicoherence of the pressure response and how much is significant (Fig. 9).

`chirp_analysis` decimates the pressure to the chirp's band, computes its bicoherence
(`spa.openloop.spectra.bicoherence`, bounded by default), the significance threshold for its
number of segments, and summarises the map by the fraction of the principal domain above the
threshold (the bins next to DC left out). `chirp_reference` does the same for the linear
reference (`spa.openloop.reference`) driven by the run's input: its fraction is what the test
reports for a plant without any nonlinearity. `noise_spread` repeats the analysis of a
simulated run over fresh sensor noise (`spa.openloop.replicas`) to show how much of a
difference between settings is noise.

The simulated sensor adds a damped ringing after every valve edge. It is locked to the
edges, so the bicoherence reads it as coupling. For a simulated dataset every row is
therefore given two ways, over the same noise seeds: as the sensor logs it
(``significant_fraction``) and with the sensor's noise but without its ringing
(``significant_fraction_no_ringing``). The linear reference goes through the same sensor as
the run whose input drives it (its ringing after that run's valve edges, its noise seeds),
so that each column compares like with like.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa import _checks, _signal
from spa.model.modulators import Modulator
from spa.model.params import ValveParams
from spa.openloop._arrays import run_columns, uniform_step
from spa.openloop.reference import linear_reference
from spa.openloop.replicas import is_simulated, noise_replicates, through_sensor
from spa.openloop.spectra import (
    bicoherence,
    mean_bicoherence,
    principal_domain_mask,
    segment_count,
    significance_threshold,
    significant_fraction,
)
from spa.synthetic import Sensor

__all__ = [
    "chirp_analysis",
    "chirp_bicoherence",
    "chirp_reference",
    "no_ringing_spread",
    "noise_spread",
]


def chirp_bicoherence(
    p: npt.ArrayLike,
    dt: float,
    *,
    nfft: int = 256,
    overlap: float = 0.5,
    decimate: int = 1,
    normalisation: str = "bounded",
    alpha: float = 0.01,
    dc_bins: int = 2,
) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Bicoherence of a uniformly sampled pressure record and its summary.

    Parameters
    ----------
    p : array_like of float, shape (n,)
        Pressure (bar), sampled every ``dt``.
    dt : float
        Sample period, s.
    nfft : int, default 256
        Segment and FFT length (`spa.openloop.spectra.bicoherence`).
    overlap : float, default 0.5
        Segment overlap fraction.
    decimate : int, default 1
        Downsampling factor applied first (anti-aliasing FIR filter, zero phase,
        ``scipy.signal.decimate``), so that the map covers the band of the chirp rather than
        the sensor's noise up to half its logging rate: a 0.1–100 Hz chirp logged at 1 kHz
        is analysed at 250 Hz with ``decimate = 4``.
    normalisation : {"bounded", "hosa"}, default "bounded"
        As `spa.openloop.spectra.bicoherence`.
    alpha : float, default 0.01
        False-alarm probability of the significance threshold.
    dc_bins : int, default 2
        Rows ``f2 < dc_bins*fs/nfft`` left out of the summaries: the DC bin and the one next
        to it hold the leakage of the record's slow trends (the pressure's own rise, the
        chirp's start at 0.1 Hz).

    Returns
    -------
    f : numpy.ndarray, shape (nfft,)
        Frequency axis in Hz.
    bic : numpy.ndarray, shape (nfft, nfft)
        Bicoherence map.
    summary : dict
        ``fs`` (Hz, after decimation), ``nfft``, ``n_segments``, ``normalisation``,
        ``threshold`` (`spa.openloop.spectra.significance_threshold` with ``alpha``; NaN for
        ``"hosa"``, whose values have no such tail), ``fmin`` (Hz: the rows ``f2 < fmin``
        next to DC are left out of the summaries), ``significant_fraction`` (of the
        principal domain above the threshold, NaN for ``"hosa"``), and ``mean_bicoherence``,
        ``median_bicoherence``, ``max_bicoherence`` over the same domain.
    """
    q = _checks.integer("decimate", decimate)
    n_dc = _checks.integer("dc_bins", dc_bins, minimum=0)
    x = np.asarray(p, dtype=np.float64)
    if q > 1:
        x = _signal.decimate(x, q)
    fs = 1.0 / (_checks.positive("dt", dt, "s") * q)
    f, bic = bicoherence(x, fs, nfft=nfft, overlap=overlap, normalisation=normalisation)
    fmin = n_dc * fs / nfft
    mask = principal_domain_mask(f, fmin=fmin)
    k = segment_count(x.size, nfft, overlap)
    bounded = normalisation == "bounded"
    threshold = significance_threshold(k, alpha) if bounded else math.nan
    fraction = significant_fraction(f, bic, threshold, fmin) if bounded else math.nan
    return (
        f,
        bic,
        {
            "fs": fs,
            "nfft": int(nfft),
            "n_segments": k,
            "normalisation": normalisation,
            "threshold": threshold,
            "fmin": fmin,
            "significant_fraction": fraction,
            "mean_bicoherence": mean_bicoherence(f, bic, fmin=fmin),
            "median_bicoherence": float(np.median(bic[mask])),
            "max_bicoherence": float(bic[mask].max()),
        },
    )


def chirp_analysis(
    run: pd.DataFrame, **options: Any
) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Bicoherence of the pressure response to a chirp input (Fig. 9).

    Parameters
    ----------
    run : pandas.DataFrame
        Run table with ``t`` (s, uniformly sampled) and ``p`` (bar).
    **options
        ``nfft``, ``overlap``, ``decimate``, ``normalisation``, ``alpha``, ``dc_bins``: as
        `chirp_bicoherence`.

    Returns
    -------
    f, bic, summary
        As `chirp_bicoherence`.

    Raises
    ------
    ValueError
        If a column is missing, ``t`` is not uniformly sampled, or an option is out of range.
    """
    t, p = run_columns(run, ("t", "p"), "chirp_analysis")
    dt = uniform_step(t, "chirp_analysis (a bicoherence)", rtol=1e-3)
    return chirp_bicoherence(p, dt, **options)


def _spread(name: str, fractions: list[float]) -> dict[str, float]:
    """``name`` (the first seed's), ``name_min`` and ``name_max`` over the seeds."""
    return {
        name: fractions[0],
        f"{name}_min": float(np.min(fractions)),
        f"{name}_max": float(np.max(fractions)),
    }


def no_ringing_spread(meta: Mapping[str, Any], seeds: int, **options: Any) -> dict[str, float]:
    """A simulated chirp run's significant fraction without the sensor's ringing.

    Parameters
    ----------
    meta : mapping
        The run's metadata (a simulated run: `spa.openloop.replicas.is_simulated`).
    seeds : int
        Noise realisations (>= 1): the run's own seed and ``seeds - 1`` others, those of
        `noise_spread`.
    **options
        As `chirp_analysis`.

    Returns
    -------
    dict
        ``significant_fraction_no_ringing``: the run re-simulated with its own noise and ADC
        step but without the ringing after the valve edges; ``_min`` and ``_max`` over the
        seeds. Empty for a run that is not the simulator's.
    """
    n = _checks.integer("seeds", seeds)
    if not is_simulated(meta):
        return {}
    dt = 1.0 / Sensor.from_mapping(meta["sensor"]).fs
    quiet = [
        chirp_bicoherence(p, dt, **options)[2]["significant_fraction"]
        for p in noise_replicates(meta, n, ringing=False, first=0)
    ]
    return _spread("significant_fraction_no_ringing", quiet)


def chirp_reference(
    run: pd.DataFrame,
    params: ValveParams,
    modulators: Iterable[Mapping[str, Any] | Modulator],
    meta: Mapping[str, Any] | None = None,
    seeds: int = 1,
    **options: Any,
) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """The linear reference's row of a chirp table: a run's input through a linear plant.

    Parameters
    ----------
    run, params, modulators
        A chirp run (its ``t`` and ``u`` drive the reference), the dataset's parameters and
        its chirp runs' settings: as `spa.openloop.reference.linear_reference`.
    meta : mapping, optional
        The run's metadata. For a simulated run logged at every controller step the
        reference is logged by the run's sensor (`spa.openloop.replicas.through_sensor`):
        the ringing after the run's valve edges and the noise of its seeds, as the runs are.
    seeds : int, default 1
        Noise realisations, as `noise_spread` (with ``meta`` only).
    **options
        As `chirp_analysis`.

    Returns
    -------
    f, bic : numpy.ndarray
        As `chirp_analysis`: of the reference as logged (through the run's sensor with
        ``meta``, else noise-free).
    row : dict
        ``run``, ``modulator`` and ``setting`` all ``"linear"``, ``gain`` 1, ``tau_m`` (s)
        and `chirp_analysis`'s summary; through the sensor also the columns of
        `noise_spread` and `no_ringing_spread`.
    """
    n = _checks.integer("seeds", seeds)
    reference, tags = linear_reference(run, params, modulators)
    clean = reference["p"].to_numpy()
    recorded = None if meta is None else through_sensor(clean, run, meta)
    if recorded is None:
        f, bic, summary = chirp_analysis(reference, **options)
        return f, bic, {**tags, **summary}
    dt = float(meta["controller_dt"])

    def logged(replicate: int, ringing: bool) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
        p = through_sensor(clean, run, meta, replicate, ringing=ringing)
        return chirp_bicoherence(p, dt, **options)

    f, bic, summary = chirp_bicoherence(recorded, dt, **options)
    summaries = [summary] + [logged(r, True)[2] for r in range(1, n)]
    quiet = [logged(r, False)[2]["significant_fraction"] for r in range(n)]
    return (
        f,
        bic,
        {
            **tags,
            **summary,
            **_seed_spread(summaries),
            **_spread("significant_fraction_no_ringing", quiet),
        },
    )


def noise_spread(
    meta: Mapping[str, Any], recorded: Mapping[str, Any], seeds: int, **options: Any
) -> dict[str, float]:
    """Spread of a simulated run's bicoherence summary over sensor-noise seeds.

    Parameters
    ----------
    meta : mapping
        The run's metadata (a simulated run: `spa.openloop.replicas.is_simulated`).
    recorded : mapping
        `chirp_analysis`'s summary of the recorded run (seed 0).
    seeds : int
        Noise realisations in all, the recorded one included (>= 1); ``seeds - 1`` runs are
        re-simulated (`spa.openloop.replicas.noise_replicates`).
    **options
        As `chirp_analysis`.

    Returns
    -------
    dict
        ``seeds``, and over them ``significant_fraction_sd`` (sample sd), ``_min``, ``_max``
        and ``mean_bicoherence_sd``.
    """
    n = _checks.integer("seeds", seeds)
    dt = 1.0 / Sensor.from_mapping(meta["sensor"]).fs
    summaries = [recorded]
    summaries += [chirp_bicoherence(p, dt, **options)[2] for p in noise_replicates(meta, n - 1)]
    return _seed_spread(summaries)


def _seed_spread(summaries: list[Mapping[str, Any]]) -> dict[str, float]:
    """`noise_spread`'s columns from the summaries of every seed (the recorded one first)."""
    n = len(summaries)
    fractions = [float(s["significant_fraction"]) for s in summaries]
    means = [float(s["mean_bicoherence"]) for s in summaries]
    return {
        "seeds": n,
        "significant_fraction_sd": float(np.std(fractions, ddof=1)) if n > 1 else math.nan,
        "significant_fraction_min": float(np.min(fractions)),
        "significant_fraction_max": float(np.max(fractions)),
        "mean_bicoherence_sd": float(np.std(means, ddof=1)) if n > 1 else math.nan,
    }
