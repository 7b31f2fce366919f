"""Records and their files: one reading layer, writers, campaign manifests.

The reading layer (:func:`read_record`) takes every supported format, column choice, units,
windows and scales (:mod:`driveid.io.tables`, :mod:`driveid.io.units`,
:mod:`driveid.io.reading`).
"""

from driveid.io.files import SUFFIXES, ensure_writable, read_record, write_record
from driveid.io.manifest import (
    MANIFEST_NAME,
    Manifest,
    ManifestRun,
    manifest_from_dict,
    read_manifest,
    write_manifest,
)
from driveid.io.reading import COLUMN_ALIASES, parse_scale
from driveid.io.record import DEFAULT_UNITS, MIN_SAMPLES, Record, record_from_table
from driveid.io.tables import READABLE_SUFFIXES, Table, read_table
from driveid.io.units import UNIT_CONVERSIONS, split_header, to_si

__all__ = [
    "Record",
    "read_record",
    "write_record",
    "ensure_writable",
    "SUFFIXES",
    "READABLE_SUFFIXES",
    "Table",
    "read_table",
    "record_from_table",
    "parse_scale",
    "COLUMN_ALIASES",
    "UNIT_CONVERSIONS",
    "split_header",
    "to_si",
    "DEFAULT_UNITS",
    "MIN_SAMPLES",
    "Manifest",
    "ManifestRun",
    "MANIFEST_NAME",
    "read_manifest",
    "write_manifest",
    "manifest_from_dict",
]
