"""Exceptions and warnings of driveid.

Every exception also subclasses a builtin so that callers can catch either, e.g.
``except ValueError`` catches a :class:`RecordError`.
"""

__all__ = [
    "DriveIdError",
    "RecordError",
    "ParameterError",
    "IdentificationError",
    "SimulationError",
    "FileFormatError",
    "OverwriteError",
    "ConfigError",
    "DriveIdWarning",
    "RecordWarning",
    "IdentificationWarning",
]


class DriveIdError(Exception):
    """Base class of all driveid errors."""


class RecordError(DriveIdError, ValueError):
    """A record (time series) breaks a rule: non-finite, unsorted, too short, corrupted."""


class ParameterError(DriveIdError, ValueError):
    """A model or estimator parameter is outside its physical or valid range."""


class IdentificationError(DriveIdError, ValueError):
    """The data cannot support the requested identification (too few peaks, no oscillation)."""


class SimulationError(DriveIdError, RuntimeError):
    """A simulation could not be carried out as requested."""


class FileFormatError(DriveIdError, ValueError):
    """A file cannot be read as a record (unknown columns, missing variables, bad header)."""


class OverwriteError(DriveIdError, FileExistsError):
    """Writing would overwrite an existing file; pass ``overwrite=True`` (CLI ``--overwrite``)."""


class ConfigError(DriveIdError, ValueError):
    """A configuration file or mapping has unknown keys, missing values or bad numbers."""


class DriveIdWarning(UserWarning):
    """Base class of all driveid warnings."""


class RecordWarning(DriveIdWarning):
    """A record was repaired, or contains something an analysis should not use."""


class IdentificationWarning(DriveIdWarning):
    """An estimate is available but weaker than usual (few peaks, poor fit)."""
