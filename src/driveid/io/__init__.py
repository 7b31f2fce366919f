"""Records and their files: Record, CSV/NPZ/MATLAB readers and writers, campaign manifests."""

from driveid.io.files import SUFFIXES, ensure_writable, read_record, write_record
from driveid.io.manifest import (
    MANIFEST_NAME,
    Manifest,
    ManifestRun,
    manifest_from_dict,
    read_manifest,
    write_manifest,
)
from driveid.io.record import DEFAULT_UNITS, MIN_SAMPLES, Record

__all__ = [
    "Record",
    "read_record",
    "write_record",
    "ensure_writable",
    "SUFFIXES",
    "DEFAULT_UNITS",
    "MIN_SAMPLES",
    "Manifest",
    "ManifestRun",
    "MANIFEST_NAME",
    "read_manifest",
    "write_manifest",
    "manifest_from_dict",
]
