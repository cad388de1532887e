"""Energy: flight energy from the rotor model (compute energy comes with the QoS work)."""

from alight.energy.flight import RotorPowerModel, flight_energy_J

__all__ = ["RotorPowerModel", "flight_energy_J"]
