"""Bridges to real vehicles and recorded flights. A real vehicle or a recording drives the same
``Pipeline`` the simulator drives. NED/FRD exists only here, and :mod:`alight.interfaces.frames` holds every
conversion.

- The MAVLink autopilot bridge (``mavlink_bridge``, ``bridge_run``; docs/interfaces.md): PX4 OFFBOARD,
  ArduPilot GUIDED, LANDING_TARGET; camera sources (``camera_source``); the emulated autopilot behind
  ``alight sitl`` (``sitl``).
- Recorded flights (docs/replay.md, docs/export.md): ``replay_readers`` (PX4 ULog via pyulog, ROS 1 / ROS 2
  bags via rosbags, with the topic mapping ``replay_mapping.yaml``), ``replay`` (``alight replay``: a
  preset's Pipeline run on a recording), ``rosbag_writer`` (``alight fly --bag``) and ``mcap_export``
  (``alight fly --mcap``, Foxglove schemas).

The submodules import pymavlink, OpenCV and the log libraries on use; this package's ``__init__`` imports
nothing.
"""
