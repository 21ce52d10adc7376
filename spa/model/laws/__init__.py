"""The actuator's two-mode laws, with the paper's as the nested case (docs/model.md,
"The general two-mode model").

* :mod:`~spa.model.laws.value` – :class:`Laws`, the typed value a
  :class:`~spa.model.params.ValveParams` carries in its ``laws`` field;
* :mod:`~spa.model.laws.rates` – ``f_open``, ``f_closed`` and their slopes;
* :mod:`~spa.model.laws.timemap` – exact simulation of each mode by its time map;
* :mod:`~spa.model.laws.equilibrium` – the averaged equilibrium and time constant.
"""

from spa.model.laws.value import DEFAULT_KNOTS, Laws, laws_from

__all__ = ["DEFAULT_KNOTS", "Laws", "laws_from"]
