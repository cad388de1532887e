"""Bridges to real vehicles and recorded flights: the MAVLink autopilot bridge (PX4 OFFBOARD, ArduPilot
GUIDED, LANDING_TARGET), the emulated autopilot behind ``alight sitl``, camera sources, and recorded-flight
replay and export. A real vehicle drives the same ``Pipeline`` the simulator drives. NED/FRD exists only
here, and :mod:`alight.interfaces.frames` holds every conversion.

The submodules import pymavlink and OpenCV on use; this package's ``__init__`` imports nothing.
"""
