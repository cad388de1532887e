"""Bridges to real vehicles and recorded flights. Conversion to NED/FRD happens only here.

Recorded flights (docs/replay.md, docs/export.md): ``replay_readers`` (PX4 ULog via pyulog, ROS 1 / ROS 2
bags via rosbags, with the topic mapping ``replay_mapping.yaml``), ``replay_frames`` (NED/FRD to ENU/FLU),
``replay`` (``alight replay``: a preset's Pipeline run on a recording), ``rosbag_writer`` (``alight fly
--bag``) and ``mcap_export`` (``alight fly --mcap``, Foxglove schemas). The MAVLink autopilot bridge
(DESIGN.md) drives the same ``Pipeline`` the simulator drives.
"""
