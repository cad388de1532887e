"""Which extra installs an optional dependency: the one-line message a command gives when it is missing.

The core (``pip install alight``) flies missions; the MAVLink bridge and emulator need ``alight[mavlink]``,
replay and the MCAP / ROS 2 bag exports ``alight[replay]``, the dask campaign engine ``alight[dask]``, and
``alight[all]`` installs every one of them."""

from __future__ import annotations

# top-level import name -> extra
EXTRA_OF_MODULE: dict[str, str] = {
    "pymavlink": "mavlink",
    "rosbags": "replay",
    "pyulog": "replay",
    "mcap": "replay",
    "foxglove_schemas_protobuf": "replay",
    "google": "replay",  # protobuf, which foxglove-schemas-protobuf brings
    "dask": "dask",
    "distributed": "dask",
}


def missing_dependency_message(err: ModuleNotFoundError) -> str | None:
    """``"pymavlink is not installed: pip install 'alight[mavlink]' (or 'alight[all]')"`` for a missing
    optional dependency; None when the missing module is not one (a bug, to be reported as such)."""
    top = (err.name or "").split(".")[0]
    extra = EXTRA_OF_MODULE.get(top)
    if extra is None:
        return None
    return f"{top} is not installed: pip install 'alight[{extra}]' (or 'alight[all]' for every optional part)"
