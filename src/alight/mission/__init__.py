"""The mission state machine, the guidance of each mode, the Pipeline that wires a preset's blocks, and the
presets (see README.md in this folder)."""
