"""Records and their files: the :class:`Record` type, CSV/NPZ/MATLAB readers and writers."""

from driveid.io.files import SUFFIXES, ensure_writable, read_record, write_record
from driveid.io.record import DEFAULT_UNITS, MIN_SAMPLES, Record

__all__ = [
    "Record",
    "read_record",
    "write_record",
    "ensure_writable",
    "SUFFIXES",
    "DEFAULT_UNITS",
    "MIN_SAMPLES",
]
