"""spa: exact simulation and open-loop characterisation of a pulse-driven soft pneumatic actuator.

Implements Serrano-Balbontín et al., "Open-Loop Characterisation of Soft Actuator Pressure
Regulated by Pulse-Driven Solenoid Valve", Robotics 2025, 14(12), 177.
"""

from spa.modulators import MODULATORS, check_settings, modulate
from spa.params import ValveParams
from spa.plant import charge, discharge, simulate

__all__ = [
    "MODULATORS",
    "ValveParams",
    "charge",
    "check_settings",
    "discharge",
    "modulate",
    "simulate",
]
__version__ = "0.1.0"
