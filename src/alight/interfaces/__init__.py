"""Bridges to real vehicles and recorded flights (MAVLink autopilot bridge, log replay).

Not written yet: DESIGN.md places them here, beside the pipeline, so that a real vehicle drives the same
`Pipeline` the simulator drives. Conversion to NED/FRD happens only here.
"""
