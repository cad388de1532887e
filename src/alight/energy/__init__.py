"""Energy: flight energy from the rotor model; compute energy of the onboard blocks on a device power
profile, through a powprofiler-style model of quality-of-service settings (paper 004).

``profile`` (the profiler that measures the model) is not imported here: it renders frames with the
simulator, which the onboard pipeline must not depend on.
"""

from alight.energy.compute import DeviceProfile, compute_energy_J
from alight.energy.flight import RotorPowerModel, flight_energy_J
from alight.energy.qos import (
    DEFAULT_PHASE_POLICY,
    PhasePolicy,
    QosDetector,
    QosEnergyModel,
    QosSetting,
    budget_policy,
)

__all__ = [
    "DEFAULT_PHASE_POLICY",
    "DeviceProfile",
    "PhasePolicy",
    "QosDetector",
    "QosEnergyModel",
    "QosSetting",
    "RotorPowerModel",
    "budget_policy",
    "compute_energy_J",
    "flight_energy_J",
]
