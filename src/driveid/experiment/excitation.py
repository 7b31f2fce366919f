r"""Run excitation signals on a plant and write the records as the PHO runner does.

The contract (:class:`ExcitablePlant`)
--------------------------------------
A plant applies an external force or torque ``u(t)`` [N·m or N], sampled at the
excitation's ``fs``, starting at rest, and returns a :class:`~driveid.io.record.Record` with
``t`` [s], the measured ``x`` [rad or m], ``u`` the *external* input (under feedback: the
excitation only, as :func:`driveid.identify.forced.forced.estimate_forced_pho` and
:func:`driveid.identify.forced.frf.estimate_frf` expect) and ``meta`` with ``plant``, ``units``,
``P``, ``D``, ``delay`` (0 without feedback).

:class:`SimulatedExcitationPlant` implements it with :func:`driveid.sim.simulate_drive`
(the drive's own PD feedback, if any, stays active and the excitation is added to it).
:func:`run_excitations` writes ``run_001.csv, run_002.csv, ...`` plus a manifest
``excitation.json`` (signal kind, settings, file, crest factor), refusing a folder that
already holds one and any file name that exists — checked before the first run, as in
:func:`driveid.experiment.pho.run_pho_campaign`.
"""

from __future__ import annotations

import datetime
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np

from driveid.errors import OverwriteError, ParameterError
from driveid.experiment.plant import AXIS_UNITS, resolve_simulated_plant
from driveid.io.files import write_record
from driveid.io.record import Record
from driveid.io.safe_write import atomic_write_text
from driveid.signal.excitation import Excitation
from driveid.sim.drive import DriveParams, simulate_drive
from driveid.sim.oscillator import measure

__all__ = ["ExcitablePlant", "SimulatedExcitationPlant", "ExcitationRuns", "run_excitations",
           "EXCITATION_MANIFEST"]

#: Manifest file name of an excitation campaign.
EXCITATION_MANIFEST = "excitation.json"

@runtime_checkable
class ExcitablePlant(Protocol):
    """Adapter interface of a plant driven by an external input (module notes).

    Attributes
    ----------
    name : str
        Plant name written into the manifest.
    units : {"rad", "m"}
        Rotational or translational axis.
    """

    name: str
    units: str

    def run_input(self, signal: Excitation) -> Record:
        """Apply ``signal.u`` from rest and return the record.

        Parameters
        ----------
        signal : Excitation
            Input [N·m or N] sampled at ``signal.fs`` [Hz].

        Returns
        -------
        Record
            ``t``, ``x``, ``u`` (the excitation), ``meta`` of the contract.
        """
        ...


class SimulatedExcitationPlant:
    """A simulated drive driven by an external torque (plus its own feedback, if any).

    Parameters
    ----------
    params : DriveParams or str
        The drive or a preset name of :data:`driveid.sim.presets.PRESETS`.
    body : int
        Body that receives the input and whose position is measured [-].
    noise_std : float
        White position noise, standard deviation [rad or m]; >= 0.
    seed : int, optional
        Seed of the noise generator.
    units : {"rad", "m"}, optional
        Axis units; default from the preset, else "rad".
    name : str, optional
        Plant name; default the preset name or ``"simulated"``.

    Examples
    --------
    >>> from driveid.signal.excitation import sine
    >>> plant = SimulatedExcitationPlant("testbed-a")
    >>> rec = plant.run_input(sine(frequency=2, duration=1, fs=500, amplitude=0.5))
    >>> rec.n, rec.meta["P"]
    (500, 5.0)
    """

    def __init__(self, params: DriveParams | str, *, body: int = 0, noise_std: float = 0.0,
                 seed: int | None = None, units: str | None = None,
                 name: str | None = None) -> None:
        params, units, name, body = resolve_simulated_plant(params, units=units, name=name,
                                                            body=body, noise_std=noise_std)
        self.params, self.body, self.units, self.name = params, body, units, name
        self.noise_std = float(noise_std)
        self._rng = np.random.default_rng(seed)

    def run_input(self, signal: Excitation) -> Record:
        """Simulate the drive under ``signal`` from rest (see :class:`ExcitablePlant`).

        Parameters
        ----------
        signal : Excitation
            Input [N·m or N] sampled at ``signal.fs`` [Hz].

        Returns
        -------
        Record
            Measured ``x``, the excitation ``u``, velocity ``v``; ``meta`` per the contract.
        """
        n = signal.t.size
        torque = np.zeros((self.params.n_bodies, n))
        torque[self.body] = signal.u
        result = simulate_drive(self.params, duration=(n - 1) / signal.fs, fs=signal.fs,
                                torque=torque)
        fb = self.params.feedback
        meta = {"plant": self.name, "units": dict(AXIS_UNITS[self.units]),
                "P": 0.0 if fb is None else float(fb.P),
                "D": 0.0 if fb is None else float(fb.D),
                "delay": 0.0 if fb is None else float(fb.delay),
                "excitation": signal.kind,
                "source": "driveid.experiment.SimulatedExcitationPlant"}
        rec = Record(t=result.t, x=result.x[self.body], u=signal.u[: result.t.size],
                     v=result.v[self.body], meta=meta)
        if self.noise_std == 0:
            return rec
        return measure(rec, noise_std=self.noise_std, rng=self._rng)


@dataclass(frozen=True)
class ExcitationRuns:
    """What :func:`run_excitations` measured and wrote.

    Attributes
    ----------
    records : tuple of Record
        One record per signal, in order.
    paths : tuple of Path
        The written record files.
    manifest_path : Path
        The manifest ``excitation.json``.
    """

    records: tuple
    paths: tuple
    manifest_path: Path


def run_excitations(plant: ExcitablePlant, signals: Excitation | Sequence[Excitation],
                    out_dir: str | Path, *, prefix: str = "run",
                    suffix: str = ".csv") -> ExcitationRuns:
    """Apply each signal to the plant and write numbered records plus a manifest.

    Parameters
    ----------
    plant : ExcitablePlant
        A simulated plant or a hardware adapter.
    signals : Excitation or sequence of Excitation
        The inputs, run in order (e.g. a stepped-sine grid of frequencies and amplitudes).
    out_dir : str or Path
        Folder (created); must not hold an ``excitation.json`` yet.
    prefix : str
        File name stem; files are ``{prefix}_001{suffix}``, ... [-].
    suffix : {".csv", ".npz", ".mat"}
        Record format.

    Returns
    -------
    ExcitationRuns
        Records, file paths and the manifest path.

    Raises
    ------
    OverwriteError
        If the folder holds a manifest or any file this call would write.
    ParameterError
        If ``plant`` does not implement :class:`ExcitablePlant` or no signal is given.
    """
    if not isinstance(plant, ExcitablePlant):
        raise ParameterError(
            f"plant must implement run_input(signal) -> Record; got {type(plant).__name__}")
    signals = [signals] if isinstance(signals, Excitation) else list(signals)
    if not signals or not all(isinstance(s, Excitation) for s in signals):
        raise ParameterError("signals must be one or more Excitation objects; got "
                             f"{[type(s).__name__ for s in signals]}")
    out_dir = Path(out_dir)
    manifest_path = out_dir / EXCITATION_MANIFEST
    names = [f"{prefix}_{k:03d}{suffix}" for k in range(1, len(signals) + 1)]
    clash = [n for n in [EXCITATION_MANIFEST, *names] if (out_dir / n).exists()
             or (out_dir / n).is_symlink()]
    if clash:
        raise OverwriteError(
            f"{out_dir} already holds {clash[:3]}; an excitation campaign never overwrites: "
            "choose another folder (CLI: --out)")
    out_dir.mkdir(parents=True, exist_ok=True)
    created = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
    records, paths, runs = [], [], []
    for k, (sig, fname) in enumerate(zip(signals, names, strict=True), start=1):
        rec = plant.run_input(sig)
        paths.append(write_record(rec, out_dir / fname))
        records.append(rec)
        settings = {key: (v.tolist() if isinstance(v, np.ndarray) else v)
                    for key, v in sig.settings.items()}
        runs.append({"index": k, "file": fname, "kind": sig.kind, "settings": settings,
                     "band_hz": list(sig.band), "crest_factor": sig.crest_factor})
        manifest = {"schema": "driveid-excitation/1", "plant": plant.name,
                    "units": plant.units, "created": created,
                    "complete": k == len(signals), "runs": runs}
        atomic_write_text(manifest_path, json.dumps(manifest, indent=2), overwrite=k > 1)
    return ExcitationRuns(records=tuple(records), paths=tuple(paths),
                          manifest_path=manifest_path)
