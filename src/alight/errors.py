"""The package's exception hierarchy. The CLI turns an ``AlightError`` into one line and exit status 2."""


class AlightError(Exception):
    """Base of every error alight raises on purpose."""


class ConfigError(AlightError):
    """A scenario, campaign or block configuration is invalid."""


class InputError(AlightError):
    """An input file (image, calibration, log) is missing, empty or corrupt."""


class EstimationError(AlightError):
    """A filter was fed something it cannot use (non-finite data, wrong shapes)."""


class ReplayError(InputError):
    """A recorded flight (ULog, ROS bag, MCAP) cannot be read or replayed: missing, truncated, corrupt,
    or without the topics the replay needs."""
