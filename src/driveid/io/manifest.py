"""Campaign manifests: the JSON summary of a PHO campaign (the thesis's ``.PD`` file).

The thesis's acquisition programme kept a ``.PD`` file "summarising the feedback
parameters and other information for each oscillation" (App. B.3.2). Here that file is
``manifest.json`` beside the records. :func:`read_manifest` accepts both the full form
written by :func:`driveid.experiment.run_pho_campaign` and the minimal hand-written form a
hardware user types::

    {"delay_s": 0.01377, "K": 0,
     "runs": [{"file": "r1pos.csv", "P": 1.5, "D": 0.03},
              {"file": "r1neg.csv", "P": 1.5, "D": 0.03}]}

Record files are relative to the manifest's folder and must stay inside it: an absolute
path, a ``..`` that leaves the folder or a symbolic link pointing outside is refused unless
the caller passes ``allow_outside=True`` (CLI ``--allow-outside``); nothing outside is read
before that check, so no foreign file's content can reach an error message. Reading checks
the campaign against itself (issue 12): gains or ``x0`` in the manifest that differ from the
records' own metadata are an error, a record listed twice and an interrupted campaign
(``"complete": false``) are warnings.
Unknown keys are errors, not warnings: a misspelt ``"delay"`` for ``"delay_s"`` would
otherwise silently turn a known delay into an estimated one. Free text goes under
``"notes"``.
"""

from __future__ import annotations

import json
import math
import os
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from driveid._json import to_jsonable
from driveid.errors import FileFormatError, OverwriteError, RecordWarning
from driveid.io.consistency import load_json, warn_duplicates
from driveid.io.files import read_record
from driveid.io.record import Record
from driveid.io.safe_write import atomic_write_text

__all__ = [
    "MANIFEST_NAME",
    "MANIFEST_FORMAT",
    "ManifestRun",
    "Manifest",
    "manifest_from_dict",
    "read_manifest",
    "write_manifest",
]

#: File name of a campaign manifest inside its folder.
MANIFEST_NAME = "manifest.json"
#: Value of the ``"format"`` key written by driveid.
MANIFEST_FORMAT = "driveid-pho-campaign"

_TOP_KEYS = {"format", "version", "created", "plant", "units", "delay_s", "K", "protocol",
             "complete", "runs", "notes"}
_RUN_KEYS = {"index", "file", "P", "D", "x0", "accepted", "reason", "settled_at", "n_peaks",
             "aborted", "notes"}
#: Largest manifest file read [bytes] (10 000 runs need about 3 MB).
_MAX_MANIFEST_BYTES = 64 << 20
_UNIT_SETS = {"rad": {"x": "rad", "u": "N·m", "v": "rad/s"},
              "m": {"x": "m", "u": "N", "v": "m/s"}}


def _number(value: Any, where: str, *, allow_none: bool = False) -> float | None:
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(
            value):
        raise FileFormatError(
            f"{where} must be a finite number{' or null' if allow_none else ''}; "
            f"got {value!r}"
        )
    return float(value)


@dataclass(frozen=True, kw_only=True)
class ManifestRun:
    """One oscillation of a campaign as listed in its manifest.

    Attributes
    ----------
    file : str
        Record file, relative to the manifest folder (or absolute).
    P : float
        Proportional gain [N·m/rad or N/m].
    D : float
        Derivative gain [N·m·s/rad or N·s/m].
    x0 : float or None
        Signed initial displacement [rad or m]; None if not recorded.
    accepted : bool
        False: the run failed a quality check and analyses skip it (default True).
    reason : str or None
        Why the run was rejected.
    settled_at : float or None
        Time from which the motion stayed inside the settle band [s]; None if it never
        settled within the record (the full record is kept either way).
    n_peaks : int or None
        Oscillation peaks found [-].
    aborted : bool
        True if the safety abort on the command stopped the run.
    index : int or None
        Run number in the campaign (1-based).
    notes : str or None
        Free text.
    """

    file: str
    P: float
    D: float
    x0: float | None = None
    accepted: bool = True
    reason: str | None = None
    settled_at: float | None = None
    n_peaks: int | None = None
    aborted: bool = False
    index: int | None = None
    notes: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """Return the run as a JSON-ready dict (None entries dropped).

        Returns
        -------
        dict
            Keys of the manifest's run objects.
        """
        out = {"index": self.index, "file": self.file, "P": self.P, "D": self.D,
               "x0": self.x0, "accepted": self.accepted, "reason": self.reason,
               "settled_at": self.settled_at, "n_peaks": self.n_peaks,
               "aborted": self.aborted, "notes": self.notes}
        return {k: v for k, v in out.items() if v is not None}


@dataclass(frozen=True, kw_only=True)
class Manifest:
    """A PHO campaign: its runs, the loop delay and what is known of the plant.

    Attributes
    ----------
    runs : tuple of ManifestRun
        The oscillations, in campaign order.
    delay_s : float or None
        Feedback loop delay [s]; None: to be estimated from the campaign.
    K : float or None
        Stiffness known a priori [N·m/rad or N/m] (e.g. 0); None: estimated.
    units : {"rad", "m"}
        Rotational (rad, N·m) or translational (m, N) records.
    plant : str or None
        Name of the plant.
    created : str or None
        ISO 8601 UTC time the campaign was started.
    protocol : dict
        Campaign settings (grid, x0, duration, fs, limits, settle and quality rules).
    complete : bool
        False while a campaign is still running, or if it was interrupted.
    notes : str or None
        Free text.
    folder : Path or None
        Folder the relative record paths start from (the manifest's folder).
    allow_outside : bool
        Accept record files outside ``folder`` (absolute paths, ``..``, links pointing
        out); default False. Not written to the file.
    """

    runs: tuple
    delay_s: float | None = None
    K: float | None = None
    units: str = "rad"
    plant: str | None = None
    created: str | None = None
    protocol: Mapping[str, Any] = field(default_factory=dict)
    complete: bool = True
    notes: str | None = None
    folder: Path | None = None
    allow_outside: bool = False

    def path_of(self, run: ManifestRun) -> Path:
        """Return the record file of a run.

        Parameters
        ----------
        run : ManifestRun
            A run of this manifest.

        Returns
        -------
        Path
            Absolute, or relative to the working directory if ``folder`` is None.
        """
        p = Path(run.file)
        return p if p.is_absolute() or self.folder is None else self.folder / p

    def checked_path_of(self, i: int, run: ManifestRun) -> Path:
        """Return the record file of run ``i`` after checking it stays inside the folder.

        Parameters
        ----------
        i : int
            Position of the run in :attr:`runs` (for the message) [-].
        run : ManifestRun
            The run.

        Returns
        -------
        Path
            The record file.

        Raises
        ------
        FileFormatError
            If the file is outside :attr:`folder` (absolute, ``..`` or a symbolic link
            pointing out) and :attr:`allow_outside` is False.
        """
        path = self.path_of(run)
        if self.allow_outside or self.folder is None:
            return path
        folder = Path(os.path.realpath(self.folder))
        why = None
        if Path(run.file).is_absolute():
            why = "is an absolute path"
        elif ".." in Path(run.file).parts:
            why = "contains '..'"
        else:
            real = Path(os.path.realpath(path))
            if real != folder and folder not in real.parents:
                why = "is a symbolic link (or inside one) pointing outside the campaign folder"
        if why is not None:
            raise FileFormatError(
                f"runs[{i}].file {run.file!r} {why}; a campaign reads records only inside "
                f"its own folder {self.folder}; move the file into the folder, or pass "
                "allow_outside=True (CLI: --allow-outside) if you trust the manifest")
        return path

    @property
    def accepted(self) -> tuple:
        """The runs analyses use (``accepted`` true)."""
        return tuple(r for r in self.runs if r.accepted)

    def load_records(self, *, accepted_only: bool = True) -> list[Record]:
        """Read the record files, with the run's gains in ``meta``.

        Parameters
        ----------
        accepted_only : bool
            Skip rejected runs (default).

        Returns
        -------
        list of Record
            One per run; ``meta`` holds ``P``, ``D``, ``x0`` (if known), ``x0_sign``,
            ``delay`` (if known), ``run_index``, ``units``.

        Raises
        ------
        FileFormatError
            If a file is missing or outside the folder (see :meth:`checked_path_of`), its
            position unit contradicts ``units``, or its own metadata gives other gains or
            ``x0`` than the manifest.

        Warns
        -----
        RecordWarning
            If the campaign is incomplete (``"complete": false``) or a record is listed
            more than once.
        """
        if not self.complete:
            warnings.warn(
                f"the campaign in {self.folder or 'this manifest'} is incomplete (\"complete\": "
                f"false, {len(self.runs)} run(s) listed): it was interrupted or is still "
                "running; finish it with `driveid pho run --resume` (same options), or "
                "accept that the analysis uses only the runs measured", RecordWarning,
                stacklevel=2)
        records = []
        for i, run in enumerate(self.runs):
            if accepted_only and not run.accepted:
                continue
            path = self.checked_path_of(i, run)
            if not path.is_file():
                raise FileFormatError(
                    f"run {i} ({run.file!r}): record file {path} not found; fix the \"file\" "
                    "entry (paths are relative to the manifest's folder) or remove the run"
                )
            rec = read_record(path)
            if rec.units.get("x") != _UNIT_SETS[self.units]["x"]:
                if _csv_header_has_units(path):
                    raise FileFormatError(
                        f"run {i} ({run.file!r}): position unit {rec.units.get('x')!r} in the "
                        f"file contradicts the manifest's units {self.units!r}; fix one of them"
                    )
                rec = read_record(path, units=_UNIT_SETS[self.units])
            _check_gains(i, run, rec)
            meta: dict[str, Any] = {"P": run.P, "D": run.D, "run_index": run.index or i + 1}
            if run.x0 is not None:
                meta["x0"] = run.x0
                meta["x0_sign"] = int(math.copysign(1, run.x0))
            if self.delay_s is not None:
                meta["delay"] = self.delay_s
            if self.plant is not None:
                meta.setdefault("plant", self.plant)
            records.append(rec.replace(meta=meta))
        warn_duplicates(records)
        return records

    def to_dict(self) -> dict[str, Any]:
        """Return the manifest as a JSON-ready dict (the full form).

        Returns
        -------
        dict
            ``format``, ``version``, ``created``, ``plant``, ``units``, ``delay_s``, ``K``,
            ``protocol``, ``complete``, ``runs`` (and ``notes`` if set).
        """
        out = {"format": MANIFEST_FORMAT, "version": 1, "created": self.created,
               "plant": self.plant, "units": self.units, "delay_s": self.delay_s,
               "K": self.K, "protocol": dict(self.protocol), "complete": self.complete,
               "runs": [r.to_dict() for r in self.runs]}
        if self.notes is not None:
            out["notes"] = self.notes
        return to_jsonable(out)


def _check_gains(i: int, run: ManifestRun, record: Record) -> None:
    """Refuse a run whose record's own metadata gives other P, D or x0 than the manifest."""
    for key in ("P", "D", "x0"):
        listed = getattr(run, key)
        own = record.meta.get(key)
        if listed is None or own is None:
            continue
        try:
            own = float(own)
        except (TypeError, ValueError):
            continue
        # 1e-9: both are written from the same float with 17 digits; anything larger is
        # an edited manifest or a mixed-up file, not rounding
        if not math.isclose(listed, own, rel_tol=1e-9, abs_tol=1e-12):
            raise FileFormatError(
                f"runs[{i}] ({run.file!r}): the manifest says {key} = {listed:g} but the "
                f"record's own metadata says {key} = {own:g}; one of them was edited or the "
                "file belongs to another run; fix the manifest entry")


def _csv_header_has_units(path: Path) -> bool:
    if path.suffix.lower() not in (".csv", ".txt"):
        return True  # NPZ / MAT carry units in their metadata when they have any
    with open(path, encoding="utf-8", errors="replace") as fh:
        for line in fh:
            if line.strip() and not line.lstrip().startswith("#"):
                return "[" in line or "(" in line
    return False


def _parse_run(i: int, item: Any) -> ManifestRun:
    if not isinstance(item, Mapping):
        raise FileFormatError(
            f"runs[{i}] must be an object like {{\"file\": \"r1pos.csv\", \"P\": 1.5, "
            f"\"D\": 0.03}}; got {item!r}"
        )
    unknown = set(item) - _RUN_KEYS
    if unknown:
        raise FileFormatError(
            f"runs[{i}] has unknown key(s) {sorted(unknown)}; allowed: {sorted(_RUN_KEYS)} "
            "(free text goes under \"notes\")"
        )
    for key in ("file", "P", "D"):
        if key not in item:
            raise FileFormatError(
                f"runs[{i}] has no {key!r}; every run needs \"file\", \"P\" and \"D\", e.g. "
                "{\"file\": \"r1pos.csv\", \"P\": 1.5, \"D\": 0.03}"
            )
    if not isinstance(item["file"], str) or not item["file"]:
        raise FileFormatError(f"runs[{i}].file must be a file name; got {item['file']!r}")
    accepted = item.get("accepted", True)
    aborted = item.get("aborted", False)
    for key, value in (("accepted", accepted), ("aborted", aborted)):
        if not isinstance(value, bool):
            raise FileFormatError(f"runs[{i}].{key} must be true or false; got {value!r}")
    n_peaks = item.get("n_peaks")
    if n_peaks is not None and (isinstance(n_peaks, bool) or not isinstance(n_peaks, int)):
        raise FileFormatError(f"runs[{i}].n_peaks must be an integer; got {n_peaks!r}")
    index = item.get("index")
    if index is not None and (isinstance(index, bool) or not isinstance(index, int)):
        raise FileFormatError(f"runs[{i}].index must be an integer; got {index!r}")
    for key in ("reason", "notes"):
        if item.get(key) is not None and not isinstance(item[key], str):
            raise FileFormatError(f"runs[{i}].{key} must be text; got {item[key]!r}")
    return ManifestRun(
        file=item["file"], P=_number(item["P"], f"runs[{i}].P"),
        D=_number(item["D"], f"runs[{i}].D"),
        x0=_number(item.get("x0"), f"runs[{i}].x0", allow_none=True),
        accepted=accepted, reason=item.get("reason"),
        settled_at=_number(item.get("settled_at"), f"runs[{i}].settled_at", allow_none=True),
        n_peaks=n_peaks, aborted=aborted, index=index, notes=item.get("notes"),
    )


def manifest_from_dict(data: Any, *, folder: Path | None = None,
                       source: str = "manifest") -> Manifest:
    """Validate a parsed manifest (full or minimal form) and return it.

    Parameters
    ----------
    data : dict
        The parsed JSON.
    folder : Path, optional
        Folder the relative record paths start from.
    source : str
        Name used in error messages (the file name).

    Returns
    -------
    Manifest
        The validated manifest.

    Raises
    ------
    FileFormatError
        If a key is unknown, missing or of the wrong type; the message names the key and
        the run index.
    """
    if not isinstance(data, Mapping):
        raise FileFormatError(
            f"{source}: the manifest must be a JSON object with a \"runs\" list; got "
            f"{type(data).__name__}"
        )
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise FileFormatError(
            f"{source}: unknown top-level key(s) {sorted(unknown)}; allowed: "
            f"{sorted(_TOP_KEYS)} (the delay is \"delay_s\" in seconds; free text goes under "
            "\"notes\")"
        )
    fmt = data.get("format", MANIFEST_FORMAT)
    if fmt != MANIFEST_FORMAT:
        raise FileFormatError(f"{source}: \"format\" must be {MANIFEST_FORMAT!r}; got {fmt!r}")
    runs = data.get("runs")
    if not isinstance(runs, list) or not runs:
        raise FileFormatError(
            f"{source}: \"runs\" must be a non-empty list of {{\"file\", \"P\", \"D\"}} "
            f"objects; got {runs!r}"
        )
    delay = _number(data.get("delay_s"), f"{source}: delay_s", allow_none=True)
    if delay is not None and delay < 0:
        raise FileFormatError(f"{source}: delay_s must be >= 0 [s] or null; got {delay!r}")
    units = data.get("units", "rad")
    if units not in _UNIT_SETS:
        raise FileFormatError(
            f"{source}: \"units\" must be \"rad\" (rotational) or \"m\" (translational); "
            f"got {units!r}"
        )
    protocol = data.get("protocol", {})
    if not isinstance(protocol, Mapping):
        raise FileFormatError(f"{source}: \"protocol\" must be an object; got {protocol!r}")
    complete = data.get("complete", True)
    if not isinstance(complete, bool):
        raise FileFormatError(f"{source}: \"complete\" must be true or false; got {complete!r}")
    for key in ("plant", "created", "notes"):
        if data.get(key) is not None and not isinstance(data[key], str):
            raise FileFormatError(f"{source}: {key!r} must be text; got {data[key]!r}")
    return Manifest(
        runs=tuple(_parse_run(i, item) for i, item in enumerate(runs)),
        delay_s=delay, K=_number(data.get("K"), f"{source}: K", allow_none=True),
        units=units, plant=data.get("plant"), created=data.get("created"),
        protocol=dict(protocol), complete=complete, notes=data.get("notes"), folder=folder,
    )


def read_manifest(path: str | Path, *, check_files: bool = True,
                  allow_outside: bool = False) -> Manifest:
    """Read and validate a campaign manifest (full or minimal hand-written form).

    Parameters
    ----------
    path : str or Path
        The manifest JSON file, or a campaign folder holding ``manifest.json``.
    check_files : bool
        Check that every run's record file exists and lies inside the folder (default).
    allow_outside : bool
        Accept record files outside the manifest's folder (absolute paths, ``..``,
        symbolic links pointing out); default False.

    Returns
    -------
    Manifest
        The campaign, with ``folder`` set to the manifest's folder.

    Raises
    ------
    FileNotFoundError
        If there is no manifest at ``path``.
    FileFormatError
        If the JSON is invalid, a key is unknown, missing or of the wrong type, or a
        record file is missing; the message names the key or run index and the fix.

    Examples
    --------
    >>> m = manifest_from_dict({"delay_s": 0.01377, "runs": [
    ...     {"file": "r1pos.csv", "P": 1.5, "D": 0.03}]})
    >>> m.delay_s, m.runs[0].P, m.runs[0].accepted
    (0.01377, 1.5, True)
    """
    path = Path(path)
    if path.is_dir():
        path = path / MANIFEST_NAME
    if not path.is_file():
        raise FileNotFoundError(
            f"no campaign manifest at {path}; pass the campaign folder written by "
            f"`driveid pho run` or a JSON manifest file"
        )
    if path.stat().st_size > _MAX_MANIFEST_BYTES:
        raise FileFormatError(
            f"{path.name} is {path.stat().st_size} bytes; a manifest of even 10 000 runs is "
            f"far below the limit of {_MAX_MANIFEST_BYTES} bytes; is it the right file?")
    data = load_json(path.read_bytes(), path.name)
    manifest = manifest_from_dict(data, folder=path.parent.resolve(), source=path.name)
    if allow_outside:
        manifest = _replace(manifest, allow_outside=True)
    if check_files:
        for i, run in enumerate(manifest.runs):
            manifest.checked_path_of(i, run)
            if not manifest.path_of(run).is_file():
                raise FileFormatError(
                    f"{path.name}: runs[{i}] names file {run.file!r}, which does not exist in "
                    f"{manifest.folder}; fix the \"file\" entry (relative to the manifest) or "
                    "remove the run"
                )
    return manifest


def write_manifest(manifest: Manifest, path: str | Path, *, overwrite: bool = False) -> Path:
    """Write a manifest as indented JSON.

    Parameters
    ----------
    manifest : Manifest
        The campaign.
    path : str or Path
        Destination file, or a folder (then ``folder/manifest.json``).
    overwrite : bool
        Replace an existing manifest (default: refuse). The campaign runner updates its
        own manifest after every run with ``overwrite=True``.

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    OverwriteError
        If the file exists and ``overwrite`` is False.
    """
    path = Path(path)
    if path.is_dir() and not path.is_symlink():
        path = path / MANIFEST_NAME
    if os.path.lexists(path) and not overwrite:
        raise OverwriteError(
            f"{path} exists and holds an earlier campaign; choose another folder (CLI: --out)"
        )
    # atomic, under an exclusively created temporary name: a planted manifest.json.tmp
    # link, or a link at manifest.json itself, is never written through
    text = json.dumps(manifest.to_dict(), indent=2, ensure_ascii=False) + "\n"
    atomic_write_text(path, text, overwrite=overwrite, option="--out (another folder)")
    return path


def _replace(manifest: Manifest, **changes: Any) -> Manifest:
    from dataclasses import replace

    return replace(manifest, **changes)
