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


class ImageError(InputError, ValueError):
    """What a detector was handed cannot be used: an array too large to be a camera frame, a grey image
    for a detector that needs colour, or a capture time that is not a finite number of seconds. (An
    empty, tiny or uniform image is not an error: detectors return no observation for it.)"""


class MeasurementError(EstimationError, ValueError):
    """A measurement or a time given to a filter is non-finite, outside the documented physical bounds
    (:mod:`alight.estimation.guards`), or has a malformed covariance. The filter is left untouched."""
