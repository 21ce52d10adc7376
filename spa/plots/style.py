"""The one palette and ordering of every figure: colour-blind-safe colours, modulator names
and the numeric order of settings.

Colours are the Okabe–Ito palette (Okabe and Ito, *Color Universal Design*, 2008), readable
with every common colour-vision deficiency and in grey-scale print. Each modulator type has
one colour in every figure; the settings inside a panel are coloured in their numeric order
(10 ms before 100 ms) by :func:`setting_colours`.

>>> sorted(["ipfm-100ms", "pwm-20Hz", "ipfm-10ms", "iipfm-20ms-G1.15", "iipfm-20ms"],
...        key=setting_sort_key)
['pwm-20Hz', 'ipfm-10ms', 'ipfm-100ms', 'iipfm-20ms', 'iipfm-20ms-G1.15']
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from typing import TYPE_CHECKING, Any, Final

from spa.model.modulators import MODULATOR_ORDER, REGISTRY, Modulator, get_kind
from spa.plots.words import SETTING_MARKERS

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "MODULATOR_COLOURS",
    "MODULATOR_NAMES",
    "OKABE_ITO",
    "SETTING_MARKERS",
    "TRACE_COLUMNS",
    "legend_beside",
    "minmax_indices",
    "ordered_settings",
    "setting_colours",
    "setting_kind",
    "setting_sort_key",
    "setting_styles",
    "shade",
]

#: Okabe–Ito: black, orange, sky blue, bluish green, yellow, blue, vermillion, reddish purple.
OKABE_ITO: Final[tuple[str, ...]] = (
    "#000000",
    "#E69F00",
    "#56B4E9",
    "#009E73",
    "#F0E442",
    "#0072B2",
    "#D55E00",
    "#CC79A7",
)


class _ByKind(Mapping[str, str]):
    """``kind -> attribute`` of every registered kind, in table order."""

    def __init__(self, attribute: str) -> None:
        self._attribute = attribute

    def __getitem__(self, kind: str) -> str:
        return str(getattr(REGISTRY[kind], self._attribute))

    def __iter__(self) -> Iterator[str]:
        return iter(MODULATOR_ORDER)

    def __len__(self) -> int:
        return len(REGISTRY)


#: One colour per modulator type, in every figure (yellow left out: too light on white).
MODULATOR_COLOURS: Final[Mapping[str, str]] = _ByKind("colour")

#: Display name of each modulator type (:attr:`spa.model.modulators.Modulator.name`).
MODULATOR_NAMES: Final[Mapping[str, str]] = _ByKind("name")

#: Colours of the settings inside one panel, in numeric order (no yellow, no black: black is
#: the ideal line's, grey the linear reference's).
_SEQUENCE: Final = ("#0072B2", "#E69F00", "#009E73", "#D55E00", "#CC79A7", "#56B4E9")


def setting_sort_key(label: str) -> tuple[int, float, float, str]:
    """Numeric order of a setting's label (:attr:`~spa.model.modulators.Modulator.label`).

    The order of :attr:`~spa.model.modulators.Modulator.sort_key`: type (PWM, IPFM, IIPFM,
    ΔΣM), then the setting's value as a number, then the gain. A label that is not a
    modulator label (a run id standing for two runs of one setting) sorts after its type's
    labels, or last, by name.

    Examples
    --------
    >>> setting_sort_key("ipfm-10ms") < setting_sort_key("ipfm-100ms")
    True
    """
    mod = _modulator(str(label))
    if mod is None:
        kind = next((k for k in MODULATOR_ORDER if str(label).startswith(k)), None)
        rank = MODULATOR_ORDER.index(kind) if kind else len(MODULATOR_ORDER)
        return (rank, float("inf"), float("inf"), str(label))
    return (*mod.sort_key, str(label))


def _modulator(label: str) -> Modulator | None:
    """The setting a label names, or None when it names none (or an invalid one)."""
    for kind in MODULATOR_ORDER:
        settings = get_kind(kind).parse_label(label)
        if settings is not None:
            try:
                return Modulator(kind, settings)
            except ValueError:
                return None
    return None


def ordered_settings(labels: Iterable[str]) -> list[str]:
    """The distinct labels in numeric order (:func:`setting_sort_key`)."""
    return sorted(dict.fromkeys(labels), key=setting_sort_key)


#: Lightness of the settings of one modulator type, in numeric order: the type's colour, then
#: darker, then lighter (:func:`shade`).
_SHADES: Final = (0.0, -0.4, 0.45, -0.65, 0.7)


def shade(colour: str, amount: float) -> str:
    """``colour`` mixed with white (``amount > 0``) or black (``amount < 0``).

    Parameters
    ----------
    colour : str
        Any matplotlib colour.
    amount : float
        In [-1, 1]: the share of white (positive) or black (negative) mixed in.

    Returns
    -------
    str
        The mixed colour, ``#rrggbb`` (lower case).

    Examples
    --------
    >>> shade("#0072B2", 0.0), shade("#0072B2", 1.0), shade("#0072B2", -1.0)
    ('#0072b2', '#ffffff', '#000000')
    """
    from matplotlib.colors import to_hex, to_rgb

    if not -1.0 <= amount <= 1.0:
        raise ValueError(f"amount must be in [-1, 1], got {amount}")
    rgb = to_rgb(colour)
    target = 1.0 if amount > 0 else 0.0
    return to_hex(tuple(c + abs(amount) * (target - c) for c in rgb))


def setting_kind(label: str) -> str | None:
    """The modulator type a setting's label (or a run id standing for one) names, or None.

    Examples
    --------
    >>> setting_kind("iipfm-20ms-G1.15"), setting_kind("pwm_run_b"), setting_kind("linear")
    ('iipfm', 'pwm', None)
    """
    mod = _modulator(str(label))
    if mod is not None:
        return mod.kind
    rank = setting_sort_key(label)[0]
    return MODULATOR_ORDER[rank] if rank < len(MODULATOR_ORDER) else None


def setting_styles(labels: Iterable[str]) -> dict[str, dict[str, str]]:
    """Colour and marker of each setting drawn on one axes, told apart without a legend order.

    Each setting takes its modulator type's colour (:data:`MODULATOR_COLOURS`, declared by
    the type's module); the settings of one type, in numeric order, take the markers of
    :data:`SETTING_MARKERS` and the type's colour, a darker and a lighter shade of it
    (:func:`shade`). A label of no known type is grey. So no two settings share colour and
    marker, and the same settings get the same style in every figure and every run.

    Parameters
    ----------
    labels : iterable of str
        Setting labels (:attr:`~spa.model.modulators.Modulator.label`).

    Returns
    -------
    dict
        Label -> ``{"color": "#rrggbb", "marker": str}``, in numeric order.

    Examples
    --------
    >>> s = setting_styles(["iipfm-20ms-G1.15", "pwm-20Hz", "iipfm-20ms"])
    >>> [(label, style["marker"]) for label, style in s.items()]
    [('pwm-20Hz', 'o'), ('iipfm-20ms', 'o'), ('iipfm-20ms-G1.15', 's')]
    >>> s["pwm-20Hz"]["color"] == MODULATOR_COLOURS["pwm"].lower()
    True
    """
    out: dict[str, dict[str, str]] = {}
    counts: dict[str | None, int] = {}
    for label in ordered_settings(labels):
        kind = setting_kind(label)
        k = counts[kind] = counts.get(kind, -1) + 1
        base = MODULATOR_COLOURS[kind] if kind is not None else "#808080"
        out[label] = {
            "color": shade(base, _SHADES[k % len(_SHADES)]),
            "marker": SETTING_MARKERS[k % len(SETTING_MARKERS)],
        }
    return out


def legend_beside(ax: Any, *args: Any, **kwargs: Any) -> Any:
    """``ax.legend(*args, **kwargs)`` right of the axes, top aligned: never over its data.

    Constrained layout makes room for it (the axes narrow).
    """
    kwargs = {"loc": "upper left", "bbox_to_anchor": (1.02, 1.0), "borderaxespad": 0.0} | kwargs
    return ax.legend(*args, **kwargs)


def setting_colours(n: int) -> list[str]:
    """``n`` colour-blind-safe colours for ``n`` settings drawn in one panel, in order.

    Okabe–Ito colours up to six settings; more are sampled evenly from ``viridis`` (also
    colour-blind safe, and ordered like the settings).

    Examples
    --------
    >>> setting_colours(2)
    ['#0072B2', '#E69F00']
    """
    if n < 0:
        raise ValueError(f"n must be >= 0, got {n}")
    if n <= len(_SEQUENCE):
        return list(_SEQUENCE[:n])
    from matplotlib import colormaps
    from matplotlib.colors import to_hex

    cmap = colormaps["viridis"]
    return [to_hex(cmap(0.9 * i / (n - 1))) for i in range(n)]


def new_figure(**kwargs: Any) -> Figure:
    """A new matplotlib figure, ``Figure(**kwargs)``.

    matplotlib is imported here, when a figure is first made, not when a plotting module is:
    a job that draws no figure (config ``figures``) never loads it.
    """
    from matplotlib.figure import Figure

    return Figure(**kwargs)


TRACE_COLUMNS: Final = 1500
"""Columns a trace is decimated to (:func:`minmax_indices`): about the pixel columns of the
widest panel at :data:`spa.plots.save.PNG_DPI` (10 in, less the margins, 200 dpi)."""


def minmax_indices(x: Any, ys: Iterable[Any], columns: int = TRACE_COLUMNS) -> Any:
    """The samples of a trace worth drawing: per column of ``x``, the first, last, smallest
    and largest sample of each ``y``, in order (at most ~4 per column for one ``y``).

    A line drawn through them covers the same pixels as one through every sample at
    ``columns`` pixel columns: every peak, every dip and the envelope of chattering stay.

    Parameters
    ----------
    x : array_like
        Increasing abscissa (time), finite.
    ys : iterable of array_like
        The curves drawn against ``x`` (NaN samples are kept where they are the extreme).
    columns : int
        Pixel columns across the span of ``x``.

    Returns
    -------
    numpy.ndarray of int
        Sorted indices into ``x``; every index when there are few samples.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(1000.0)
    >>> y = np.zeros(1000); y[517] = 5.0
    >>> i = minmax_indices(t, [y], columns=10)
    >>> len(i) <= 40, 517 in i, float(y[i].max())
    (True, True, 5.0)
    """
    import numpy as np

    if columns < 1:
        raise ValueError(f"columns must be >= 1, got {columns}")
    x_ = np.asarray(x, dtype=float)
    n = x_.size
    if n <= 4 * columns:
        return np.arange(n)
    span = x_[-1] - x_[0]
    col = np.minimum(((x_ - x_[0]) * (columns / span)).astype(np.int64), columns - 1)
    starts = np.flatnonzero(np.r_[True, col[1:] != col[:-1]])
    ends = np.r_[starts[1:], n] - 1
    keep = [starts, ends]
    for y in ys:
        y_ = np.nan_to_num(np.asarray(y, dtype=float), nan=0.0)
        keep.append(starts + _segment_arg(np.minimum, y_, starts))
        keep.append(starts + _segment_arg(np.maximum, y_, starts))
    return np.unique(np.concatenate(keep))


def _segment_arg(reduce: Any, y: Any, starts: Any) -> Any:
    """Offset, within each segment ``y[starts[k]:starts[k+1]]``, of its extreme by ``reduce``."""
    import numpy as np

    extreme = reduce.reduceat(y, starts)
    seg = np.repeat(np.arange(starts.size), np.diff(np.r_[starts, y.size]))
    hit = np.flatnonzero(y == extreme[seg])
    first = np.unique(seg[hit], return_index=True)[1]
    return hit[first] - starts[seg[hit[first]]]
