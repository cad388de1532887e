"""Energy: flight energy from the rotor model; compute energy of the onboard blocks on a device power
profile, through a powprofiler-style model of quality-of-service settings (paper 004).

A leaf: it depends on no pipeline stage. The detector that runs at a QoS setting is a perception block
(:mod:`alight.perception.qos_detector`); the profiler that measures the model renders frames with the
simulator and lives with the evaluation tooling (:mod:`alight.evaluation.qos_profile`).
"""

from alight.energy.compute import DeviceProfile, compute_energy_J
from alight.energy.flight import RotorPowerModel, flight_energy_J
from alight.energy.qos import (
    DEFAULT_PHASE_POLICY,
    PhasePolicy,
    QosEnergyModel,
    QosSetting,
    budget_policy,
)

__all__ = [
    "DEFAULT_PHASE_POLICY",
    "DeviceProfile",
    "PhasePolicy",
    "QosEnergyModel",
    "QosSetting",
    "RotorPowerModel",
    "budget_policy",
    "compute_energy_J",
    "flight_energy_J",
]
