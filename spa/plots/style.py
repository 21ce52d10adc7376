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

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "MODULATOR_COLOURS",
    "MODULATOR_NAMES",
    "OKABE_ITO",
    "ordered_settings",
    "setting_colours",
    "setting_sort_key",
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
