"""Closed-loop pressure control through the pulse modulator (issue: PI design and exact simulation).

* :mod:`spa.closedloop.controller` – :class:`PIController`, one value type for P, PI,
  gain-scheduled PI and feed-forward;
* :mod:`spa.model.modulators.kernels` – the per-step law of each modulator, compiled;
* :mod:`spa.closedloop.loop` – :func:`simulate_closed_loop`, the exact compiled loop;
* :mod:`spa.closedloop.reference` – the same loop in plain Python from the open-loop
  functions (tests);
* :mod:`spa.closedloop.design` – local models from the averaged analysis and SIMC tuning;
* :mod:`spa.closedloop.metrics` – step and sine tracking metrics (docs/model.md section 8);
* :mod:`spa.closedloop.export` – the controller as a C99 header and an Arduino sketch;
  :mod:`spa.closedloop.stepper` – :class:`ControllerStepper`, the same law in Python;
* :mod:`spa.closedloop.robust` – the worst case over the identification's box, robust
  ``tau_c``; :mod:`spa.closedloop.disturbance` – supply drop and sensor noise;
  :mod:`spa.closedloop.bench` – what the ``closed_loop`` stage writes of them.
"""

from __future__ import annotations

from spa._lazy import lazy_exports

_EXPORTS: dict[str, str] = {
    "ControllerStepper": "spa.closedloop.stepper",
    **dict.fromkeys(
        ("arduino_sketch", "controller_header", "export_designed", "write_controller"),
        "spa.closedloop.export",
    ),
    **dict.fromkeys(("design_pi", "feedforward", "local_models", "simc"), "spa.closedloop.design"),
    "PIController": "spa.closedloop.controller",
    "closed_loop_reference": "spa.closedloop.reference",
    **dict.fromkeys(("sine_metrics", "step_metrics"), "spa.closedloop.metrics"),
    "robust_design": "spa.closedloop.robust",
    "simulate_closed_loop": "spa.closedloop.loop",
}

__all__ = sorted(_EXPORTS)

_, __getattr__, __dir__ = lazy_exports(__name__, (), _EXPORTS)
