"""A deck that moves in 6 DoF at sea (issue 37, point 1): ``docs/sea.md`` explains the model.

Sea state (WMO code, or Hs and Tp) -> wave spectrum (Pierson-Moskowitz or JONSWAP) -> a seeded random
sea of regular components with jittered frequencies (no periodic repetition) -> encounter frequency at the
vessel's speed and relative wave direction -> a parametric response per axis (heave, roll, pitch with a
resonance each; surge, sway, yaw kinematic) -> the pad's exact pose, velocity and acceleration on a vessel
that follows a planar path.

Modules: ``spectra`` (sea-state table, PM and JONSWAP spectra), ``waves`` (random-sea synthesis,
encounter frequency), ``vessel`` (vessel classes as data, ``vessels/*.yaml``), ``response`` (per-axis
excitation and resonance), ``deck`` (the pad's ground-truth kinematics: ``DeckMotion``, ``VesselPath``,
``PadKinematics``), ``config`` (``SeaConfig``, the ``platform.sea`` settings).

``DeckMotion.pad`` gives the future as readily as the present: it is ground truth for the judge, the
renderer and the tests, never an input of the pipeline.
"""

from alight.sim.sea.config import SeaConfig
from alight.sim.sea.deck import DeckMotion, PadKinematics, VesselPath
from alight.sim.sea.response import AXES, response_coefficients
from alight.sim.sea.spectra import SEA_STATES, jonswap, pierson_moskowitz, sea_state_hs_tp
from alight.sim.sea.vessel import Vessel, load_vessel, packaged_vessels
from alight.sim.sea.waves import WaveComponents, encounter_frequency, synthesise

__all__ = [
    "AXES",
    "SEA_STATES",
    "DeckMotion",
    "PadKinematics",
    "SeaConfig",
    "Vessel",
    "VesselPath",
    "WaveComponents",
    "encounter_frequency",
    "jonswap",
    "load_vessel",
    "packaged_vessels",
    "pierson_moskowitz",
    "response_coefficients",
    "sea_state_hs_tp",
    "synthesise",
]
