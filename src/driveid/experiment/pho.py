r"""PHO campaign runner: the thesis's acquisition protocol (App. B.3.2) on any :class:`Plant`.

Protocol: a grid of proportional gains ``P_i`` with, for every ``P_i``, the same equally
stepped derivative gains ``D_j``; each (P, D) is run once from ``+x0`` and once from ``-x0``
(thesis App. B.3.2: "pairs of data files, one for oscillations with a 'positive' initial
displacement, and the other with a 'negative' initial displacement"). The thesis's
programme then "automatically detects when the oscillation has settled" and asks the user
to accept or reject it; here the acceptance is automatic, by quality checks, with the
reason written to the manifest (:mod:`driveid.io.manifest`), the ``.PD`` summary file of
the thesis.

Decisions
---------
* Settle detection keeps the *full* record and stores ``settled_at`` (no crop: nothing
  measured is thrown away; analyses find the stuck end themselves).
* Every run is written, rejected ones too (``accepted: false`` with the reason); analyses
  skip them.
* A folder that already holds a manifest is refused (:class:`~driveid.errors.OverwriteError`
  naming the fixes: another ``--out``, or ``--resume`` for an interrupted campaign); so is
  any record file name that already exists, checked before the first run. The thesis's
  programme overwrote silently (its footnote 81). A campaign folder that is a symbolic link
  is refused: the records would land somewhere the user did not name.
* Every file is written atomically (:mod:`driveid.io.safe_write`): a record has a temporary
  name until it is complete, so an interrupted run leaves no partial record. The manifest is
  rewritten after every run (``"complete": false`` until the end), so an interrupted
  campaign keeps the summary of what it measured, and ``resume=True`` (CLI ``--resume``)
  continues it: the runs listed are kept, the others are run, with the same protocol.
* Absurd requests are refused before the first run: more than ``max_runs`` runs (default
  :data:`MAX_RUNS`), or records that would not fit in memory.
"""

from __future__ import annotations

import datetime
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from driveid.errors import DriveIdError, OverwriteError, ParameterError
from driveid.experiment.plant import Plant
from driveid.io.consistency import (
    MAX_CAMPAIGN_RUNS,
    check_allocation,
    check_count,
    check_disk,
)
from driveid.io.files import read_record, write_record
from driveid.io.manifest import (
    MANIFEST_NAME,
    Manifest,
    ManifestRun,
    read_manifest,
    write_manifest,
)
from driveid.io.record import Record
from driveid.io.safe_write import TEMP_SUFFIX
from driveid.signal.envelope import noise_std
from driveid.signal.peaks import find_oscillation_peaks

#: Default fewest peaks of an accepted run: what the log decrement of the analysis needs
#: (``driveid.identify.free_decay.logdec.MIN_PEAKS``; experiment does not import identify).
MIN_DECAY_PEAKS = 5
#: Most runs a campaign plans without an explicit ``max_runs`` (CLI ``--max-runs``): the
#: thesis's largest campaign had a few hundred; 10 000 runs of 5 s are 14 h of testing.
MAX_RUNS = MAX_CAMPAIGN_RUNS
#: Bytes held per sample while a run is simulated and checked (t, x, u, v and temporaries).
_BYTES_PER_SAMPLE_RUN = 96
#: Bytes kept per sample of every finished run (t, x, u, v in the returned Campaign).
_BYTES_PER_SAMPLE_KEPT = 32
#: Bytes of one CSV line of t, x, u at 17 digits (the binary formats hold 3 doubles) [B].
CSV_BYTES_PER_SAMPLE = 75

__all__ = [
    "RunAssessment",
    "CampaignRun",
    "Campaign",
    "settle_time",
    "assess_run",
    "run_pho_campaign",
    "MAX_RUNS",
]


@dataclass(frozen=True)
class RunAssessment:
    """Outcome of the quality checks of one run.

    Attributes
    ----------
    accepted : bool
        True if the run is usable for identification.
    reason : str or None
        Why it was rejected (None if accepted).
    n_peaks : int
        Oscillation peaks found [-] (0 if none could be found).
    settled_at : float or None
        Time from which the motion stays inside the settle band [s]; None if it never
        settles within the record.
    """

    accepted: bool
    reason: str | None
    n_peaks: int
    settled_at: float | None


@dataclass(frozen=True)
class CampaignRun:
    """One run of a campaign: its gains, record, file and acceptance.

    Attributes
    ----------
    index : int
        Run number, 1-based [-].
    P : float
        Proportional gain [N·m/rad or N/m].
    D : float
        Derivative gain [N·m·s/rad or N·s/m].
    x0 : float
        Signed initial displacement [rad or m].
    record : Record
        The measured record (as written).
    path : Path
        The record file.
    assessment : RunAssessment
        Acceptance, reason, peaks, settle time.
    """

    index: int
    P: float
    D: float
    x0: float
    record: Record
    path: Path
    assessment: RunAssessment

    @property
    def accepted(self) -> bool:
        """True if the run passed the quality checks."""
        return self.assessment.accepted


@dataclass(frozen=True)
class Campaign:
    """A finished PHO campaign.

    Attributes
    ----------
    runs : tuple of CampaignRun
        All runs in campaign order.
    manifest : Manifest
        What was written to ``manifest_path``.
    manifest_path : Path
        The manifest file.
    """

    runs: tuple
    manifest: Manifest
    manifest_path: Path

    @property
    def accepted(self) -> tuple:
        """The accepted runs."""
        return tuple(r for r in self.runs if r.accepted)

    def records(self, *, accepted_only: bool = True) -> list[Record]:
        """Return the runs' records (``meta`` holds ``P``, ``D``, ``x0``, ``delay``).

        Parameters
        ----------
        accepted_only : bool
            Skip rejected runs (default).

        Returns
        -------
        list of Record
            In campaign order.
        """
        return [r.record for r in self.runs if r.accepted or not accepted_only]


def _quantum(record: Record) -> float:
    measured = record.meta.get("measurement") or {}
    if measured.get("quantum"):
        return float(measured["quantum"])
    steps = np.abs(np.diff(record.x))
    steps = steps[steps > 0]
    if steps.size:
        smallest = float(steps.min())
        if np.allclose(steps / smallest, np.round(steps / smallest), atol=1e-6):
            return smallest  # an encoder grid
    return 0.0


def settle_time(record: Record, *, tol: float | None = None,
                window: float = 0.2) -> float | None:
    """Find when an oscillation has died out: the start of the final still stretch.

    Parameters
    ----------
    record : Record
        Position record [rad or m].
    tol : float, optional
        Half-width of the settle band around the final position [rad or m]; default the
        larger of 3 encoder quanta, 6 noise standard deviations and 0.1 % of the range.
    window : float
        Shortest still stretch at the end that counts as settled [s]; > 0.

    Returns
    -------
    float or None
        Time [s] after which ``x`` stays within ``tol`` of its final value, if that lasts
        at least ``window`` up to the end of the record; None otherwise.

    Examples
    --------
    >>> t = np.arange(2000) * 1e-3
    >>> x = np.where(t < 0.6, np.cos(10 * t) * (0.6 - t), 0.0)
    >>> settle_time(Record(t=t, x=x))
    0.6
    """
    if not window > 0:
        raise ParameterError(f"window must be positive [s]; got {window!r}")
    x = np.asarray(record.x)
    if tol is None:
        tol = max(3 * _quantum(record), 6 * noise_std(x), 1e-3 * float(np.ptp(x)))
    n_end = max(3, int(round(0.5 * window * record.fs)))
    end = float(np.median(x[-n_end:]))
    away = np.flatnonzero(np.abs(x - end) > tol)
    start = int(away[-1]) + 1 if away.size else 0
    if start >= x.size or record.t[-1] - record.t[start] < window:
        return None
    return float(record.t[start])


def assess_run(record: Record, *, min_peaks: int = MIN_DECAY_PEAKS, settle_tol: float | None = None,
               settle_window: float = 0.2) -> RunAssessment:
    """Accept or reject one PHO run by the quality checks, giving the reason.

    Parameters
    ----------
    record : Record
        A run from :meth:`Plant.run_pd` (``meta["aborted"]``, ``meta["saturation"]``).
    min_peaks : int
        Fewest oscillation peaks (release included) for a decay fit [-]; >= 2.
    settle_tol : float, optional
        Settle band [rad or m]; see :func:`settle_time`.
    settle_window : float
        Settle window [s]; see :func:`settle_time`.

    Returns
    -------
    RunAssessment
        Checked in this order: aborted by the safety limit, corrupted samples, saturated
        command, never oscillated, too few peaks.
    """
    if not (isinstance(min_peaks, int) and min_peaks >= 2):
        raise ParameterError(f"min_peaks must be an int >= 2; got {min_peaks!r}")
    meta = record.meta
    settled = settle_time(record, tol=settle_tol, window=settle_window)

    def reject(reason: str, n_peaks: int = 0) -> RunAssessment:
        return RunAssessment(False, reason, n_peaks, settled)

    if meta.get("aborted"):
        return reject(f"aborted: {meta.get('abort_reason') or 'safety limit on the command'}")
    if record.corrupted:
        i0, i1 = record.corrupted[0]
        return reject(f"corrupted samples between t={record.t[i0]:.4g} s and "
                      f"t={record.t[i1 - 1]:.4g} s; repeat the run")
    saturation = meta.get("saturation")
    if saturation is not None and record.u is not None:
        n_sat = int(np.sum(np.abs(record.u) >= float(saturation) * (1 - 1e-9)))
        if n_sat:
            return reject(f"saturated: the command reached ±{float(saturation):g} on {n_sat} "
                          "sample(s); lower P or x0")
    try:
        peaks = find_oscillation_peaks(record)
    except DriveIdError as exc:
        return reject(f"never oscillated: {exc}")
    n = len(peaks)
    if n < 3:
        # a release and a single overshoot (or none) is no oscillation
        return reject(f"never oscillated: {n} peak(s); lower D or raise P", n)
    if n < min_peaks:
        return reject(f"too few peaks: {n} < {min_peaks}; raise x0 or lower D", n)
    return RunAssessment(True, None, n, settled)


def _grid(name: str, values) -> list[float]:
    try:
        out = [float(v) for v in values]
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a sequence of numbers; got {values!r}") from None
    if not out or not all(math.isfinite(v) for v in out):
        raise ParameterError(f"{name} must be a non-empty sequence of finite numbers; got "
                             f"{values!r}")
    return out


def _fmt(value: float) -> str:
    return f"{value:.6g}"


def run_pho_campaign(
    plant: Plant,
    *,
    P_values: Sequence[float],
    D_values: Sequence[float] | None = None,
    D_start: float | None = None,
    D_step: float | None = None,
    n_D: int | None = None,
    x0: float,
    duration: float,
    fs: float = 1000.0,
    out_dir: str | Path,
    abort_limit: float | None = None,
    min_peaks: int = MIN_DECAY_PEAKS,
    settle_tol: float | None = None,
    settle_window: float = 0.2,
    K: float | None = None,
    suffix: str = ".csv",
    progress: Callable[[int, int, CampaignRun], None] | None = None,
    resume: bool = False,
    max_runs: int = MAX_RUNS,
) -> Campaign:
    """Run a PHO campaign: every (P_i, D_j) from +x0 and -x0, checked, written, summarised.

    Parameters
    ----------
    plant : Plant
        The plant (:class:`~driveid.experiment.plant.SimulatedPlant`, a hardware adapter).
    P_values : sequence of float
        Proportional gains P_i [N·m/rad or N/m].
    D_values : sequence of float, optional
        Derivative gains D_j [N·m·s/rad or N·s/m], the same for every P_i. Alternatively
        ``D_start``, ``D_step``, ``n_D``.
    D_start : float, optional
        First derivative gain [N·m·s/rad or N·s/m].
    D_step : float, optional
        Step between derivative gains [N·m·s/rad or N·s/m].
    n_D : int, optional
        Number of derivative gains [-].
    x0 : float
        Magnitude of the initial displacement [rad or m]; > 0.
    duration : float
        Length of each run [s].
    fs : float
        Sampling rate [Hz].
    out_dir : str or Path
        Campaign folder (created); must not already hold a manifest (unless ``resume``) and
        must not be a symbolic link.
    abort_limit : float, optional
        Safety limit on ``|u|`` [N·m or N]; default twice the largest initial command,
        ``2 max|P| x0`` (a decaying oscillation stays near ``P x0``; a growing one trips it).
    min_peaks : int
        Fewest oscillation peaks for an accepted run [-].
    settle_tol : float, optional
        Settle band [rad or m] (see :func:`settle_time`).
    settle_window : float
        Settle window [s].
    K : float, optional
        Stiffness known a priori [N·m/rad or N/m] written to the manifest (e.g. 0).
    suffix : {".csv", ".npz", ".mat"}
        Record file format.
    progress : callable, optional
        Called as ``progress(k, n_runs, run)`` after each run (also for the runs kept by
        ``resume``).
    resume : bool
        Continue the interrupted campaign in ``out_dir`` (``"complete": false``): runs it
        lists are read back, not repeated; a record written but not yet listed is run
        again. The protocol (grid, x0, duration, fs, limits) must be the one it started
        with. Without a campaign in ``out_dir`` it starts one.
    max_runs : int
        Most runs accepted [-]; default :data:`MAX_RUNS`.

    Returns
    -------
    Campaign
        The runs with their records and acceptance, and the manifest path.

    Raises
    ------
    OverwriteError
        If ``out_dir`` already holds a manifest (without ``resume``, or a complete one), or
        a file the campaign would write.
    ParameterError
        If the grid or a setting is invalid, ``out_dir`` is a symbolic link, the grid has
        more than ``max_runs`` runs, the records would not fit in memory, or ``resume``
        finds another protocol.
    """
    P_grid = _grid("P_values", P_values)
    if D_values is not None:
        if any(v is not None for v in (D_start, D_step, n_D)):
            raise ParameterError("give D_values or D_start/D_step/n_D, not both")
        D_grid = _grid("D_values", D_values)
    else:
        if D_start is None or D_step is None or n_D is None:
            raise ParameterError(
                "give D_values, or all of D_start, D_step and n_D (equally stepped D); got "
                f"D_start={D_start!r}, D_step={D_step!r}, n_D={n_D!r}")
        if not (isinstance(n_D, int) and n_D >= 1):
            raise ParameterError(f"n_D must be an int >= 1; got {n_D!r}")
        # 12 digits: 0.1 + 2·0.02 is 0.14, not 0.14000000000000001, in names and manifest
        D_grid = _grid("D_values", [float(f"{D_start + j * D_step:.12g}") for j in range(n_D)])
    if not (isinstance(x0, (int, float)) and math.isfinite(x0) and x0 > 0):
        raise ParameterError(
            f"x0 is the magnitude of the initial displacement and must be > 0 [rad or m]; "
            f"got {x0!r}")
    if abort_limit is None:
        if not any(P_grid):  # the default limit follows P: P = 0 made it 0 (issue 28)
            raise ParameterError(
                "every P value is 0: the loop's P gain is the oscillator's spring, so a "
                "PHO campaign needs P > 0 (e.g. --P 2,3,4); got P_values "
                f"{[float(p) for p in P_grid]}")
        abort_limit = 2.0 * max(abs(p) for p in P_grid) * x0
    if not (isinstance(abort_limit, (int, float)) and abort_limit > 0):
        raise ParameterError(
            f"abort_limit must be positive [N·m or N] (inf: none); got {abort_limit!r}")
    for name, value in (("duration", duration), ("fs", fs)):
        if not (isinstance(value, (int, float)) and 0 < value < math.inf):
            raise ParameterError(f"{name} must be positive and finite; got {value!r}")
    if not (isinstance(min_peaks, int) and min_peaks >= 2):
        raise ParameterError(f"min_peaks must be an int >= 2; got {min_peaks!r}")
    if suffix not in (".csv", ".npz", ".mat"):
        raise ParameterError(f'suffix must be ".csv", ".npz" or ".mat"; got {suffix!r}')
    out_dir = Path(out_dir)
    if out_dir.is_symlink():
        raise ParameterError(
            f"--out {out_dir} is a symbolic link (to {os.readlink(out_dir)}); a campaign is "
            "written only into a real folder, so that no record lands where it was not "
            "asked; pass the folder the link points to")
    if out_dir.exists() and not out_dir.is_dir():
        raise ParameterError(f"--out {out_dir} is a file; give a folder for the campaign")
    manifest_path = out_dir / MANIFEST_NAME
    n_planned = 2 * len(P_grid) * len(D_grid)
    check_count(n_planned, max_runs, f"the campaign plans 2 x {len(P_grid)} P x "
                f"{len(D_grid)} D runs", override="max_runs=N (CLI: --max-runs N)")
    n_samples = duration * fs + 1
    check_allocation(n_samples * (_BYTES_PER_SAMPLE_RUN / _BYTES_PER_SAMPLE_KEPT + n_planned),
                     _BYTES_PER_SAMPLE_KEPT,
                     f"{n_planned} run(s) of duration {duration:g} s at fs {fs:g} Hz",
                     override="shorten --duration, lower --fs or split the grid")
    check_disk(n_planned * n_samples * (CSV_BYTES_PER_SAMPLE if suffix == ".csv" else 24),
               out_dir,
               f"{n_planned} run(s) of {duration:g} s at {fs:g} Hz",
               override="shorten --duration, lower --fs, split the grid or write elsewhere")
    old = None
    if os.path.lexists(manifest_path):
        if not resume:
            raise OverwriteError(
                f"{out_dir} already holds a campaign ({MANIFEST_NAME}); choose another folder "
                "(CLI: --out), or continue an interrupted one with resume=True (CLI: "
                "--resume) - earlier campaigns are never overwritten")
        old = read_manifest(manifest_path, check_files=False)
        if old.complete:
            raise OverwriteError(
                f"{out_dir} holds a complete campaign ({len(old.runs)} runs); nothing to "
                "resume; choose another folder (CLI: --out) for a new campaign")
    plan = []
    for P in P_grid:
        for D in D_grid:
            for sign in (1, -1):
                k = len(plan) + 1
                name = (f"run-{k:03d}-P{_fmt(P)}-D{_fmt(D)}-{'pos' if sign > 0 else 'neg'}"
                        f"{suffix}")
                plan.append((k, P, D, sign * float(x0), out_dir / name))
    protocol = {"P_values": P_grid, "D_values": D_grid, "x0": float(x0),
                "duration": float(duration), "fs": float(fs), "abort_limit": abort_limit,
                "min_peaks": min_peaks, "settle_tol": settle_tol,
                "settle_window": settle_window, "order": "P, then D, then +x0/-x0"}
    listed: dict[str, ManifestRun] = {}
    if old is not None:
        _check_same_protocol(old, protocol, out_dir)
        listed = {r.file: r for r in old.runs}
        _remove_leftovers(out_dir, [p.name for *_, p in plan])
    clash = [str(p) for *_, p in plan if os.path.lexists(p) and old is None]
    if clash:
        raise OverwriteError(
            f"{out_dir} already holds {len(clash)} file(s) this campaign would write (e.g. "
            f"{clash[0]}); choose another folder (CLI: --out)")
    out_dir.mkdir(parents=True, exist_ok=True)
    created = (old.created if old is not None and old.created else
               datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"))
    delay = getattr(plant, "delay", None)
    if delay is None and old is not None:
        delay = old.delay_s
    runs: list[CampaignRun] = []

    def manifest(complete: bool) -> Manifest:
        entries = tuple(ManifestRun(
            index=r.index, file=r.path.name, P=r.P, D=r.D, x0=r.x0,
            accepted=r.assessment.accepted, reason=r.assessment.reason,
            settled_at=r.assessment.settled_at, n_peaks=r.assessment.n_peaks,
            aborted=bool(r.record.meta.get("aborted", False))) for r in runs)
        return Manifest(runs=entries, delay_s=delay_used, K=K,
                        units=getattr(plant, "units", "rad"),
                        plant=getattr(plant, "name", None), created=created,
                        protocol=protocol, complete=complete, folder=out_dir.resolve())

    delay_used = delay
    for k, P, D, start, path in plan:
        entry = listed.get(path.name)
        if entry is not None and path.is_file() and not path.is_symlink():
            runs.append(_kept_run(k, P, D, start, path, entry))
            if progress is not None:
                progress(k, len(plan), runs[-1])
            continue
        record = plant.run_pd(P=P, D=D, x0=start, duration=duration, fs=fs,
                              abort_limit=abort_limit)
        if delay_used is None and record.meta.get("delay") is not None:
            delay_used = float(record.meta["delay"])  # e.g. known only once fs is
        assessment = assess_run(record, min_peaks=min_peaks, settle_tol=settle_tol,
                                settle_window=settle_window)
        record = record.replace(meta={
            "run_index": k, "P": P, "D": D, "x0": start, "x0_sign": 1 if start > 0 else -1,
            "accepted": assessment.accepted, "reason": assessment.reason,
            "settled_at": assessment.settled_at})
        # a final-named file that is not listed is this campaign's own run, written just
        # before an interruption and never summarised: it is run again and replaced
        write_record(record, path, overwrite=old is not None)
        run = CampaignRun(index=k, P=P, D=D, x0=start, record=record, path=path,
                          assessment=assessment)
        runs.append(run)
        # rewritten after every run: an interrupted campaign keeps its summary
        write_manifest(manifest(False), manifest_path,
                       overwrite=os.path.lexists(manifest_path))
        if progress is not None:
            progress(k, len(plan), run)
    final = manifest(True)
    write_manifest(final, manifest_path, overwrite=True)
    return Campaign(runs=tuple(runs), manifest=final, manifest_path=manifest_path)


_RESUME_KEYS = ("P_values", "D_values", "x0", "duration", "fs", "abort_limit", "min_peaks",
                "settle_tol", "settle_window")


def _check_same_protocol(old: Manifest, protocol: dict, out_dir: Path) -> None:
    """Refuse to resume a campaign with other settings than it started with."""
    before = dict(old.protocol)
    differ = [f"{key} {before.get(key)!r} (campaign) vs {protocol[key]!r} (now)"
              for key in _RESUME_KEYS if before.get(key) != protocol[key]]
    if differ:
        raise ParameterError(
            f"cannot resume the campaign in {out_dir} with other settings: "
            f"{'; '.join(differ)}; repeat the options it was started with (see the "
            f"\"protocol\" of its {MANIFEST_NAME}), or start a new campaign in another folder")


def _remove_leftovers(out_dir: Path, names: list[str]) -> None:
    """Delete temporary files of this campaign's records left by a killed process."""
    if not out_dir.is_dir():
        return
    wanted = set(names)
    for item in out_dir.iterdir():
        name = item.name
        if not (name.startswith(".") and TEMP_SUFFIX in name):
            continue
        base = name[1:].split(".")
        # ".run-001-...-pos.csv.<random>.part.csv" -> "run-001-...-pos.csv"
        for cut in range(len(base), 0, -1):
            if ".".join(base[:cut]) in wanted:
                if item.is_file() or item.is_symlink():
                    item.unlink()
                break


def _kept_run(k: int, P: float, D: float, start: float, path: Path,
              entry: ManifestRun) -> CampaignRun:
    """Read back a run listed by the manifest of an interrupted campaign."""
    record = read_record(path)
    for key, value in (("P", P), ("D", D), ("x0", start)):
        own = record.meta.get(key)
        if own is not None and not math.isclose(float(own), value, rel_tol=1e-9):
            raise ParameterError(
                f"cannot resume: {path.name} holds {key} = {own} but the campaign plans "
                f"{key} = {value}; the folder was edited; start a new campaign")
    assessment = RunAssessment(entry.accepted, entry.reason, entry.n_peaks or 0,
                               entry.settled_at)
    return CampaignRun(index=k, P=P, D=D, x0=start, record=record, path=path,
                       assessment=assessment)
