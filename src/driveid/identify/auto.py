r"""Point it at a trace: classify the test, run the estimators that apply, keep the best.

The thesis's future work (de Marchi 1998, §6.1) asks to "fully automate the identification
procedure". :func:`identify_auto` does it in three steps:

1. **Which test is this?** :func:`driveid.identify._shape.classify_record` names the shape of
   each record (free decay, PHO run, sine, steps, ramps, speed plateaus, broadband excitation,
   operating record) with its evidence; several records take the shape most of them show.
2. **Which estimators apply?** Each shape has its candidates, the thesis's own method and
   the whole-record ones that cross-check it (e.g. output error, Hilbert and the peak log
   decrement on a free decay, Eqs. 2.166-2.175; the campaign fit and the peak analysis of a
   PHO campaign, 2.180-2.194).
3. **Which answer?** The candidates that ran are ranked by their adequacy verdict
   (``diagnostics["adequacy"]["adequate"]``: white prewhitened residuals and no richer
   structure needed) — one that passes comes first — then by the order of the shape's list
   (the estimator nearest the Cramér–Rao bound first). A failed check does not rank below
   an estimator that runs none: that one is not known to fit better. The others' values
   stand beside the chosen ones, with a warning where two disagree by more than 3 combined
   standard errors.

The result is the chosen estimator's :class:`Estimate` (so ``validate`` and ``report`` read it
as usual) with ``diagnostics["auto"]``: shape, evidence, candidates, the reason for the choice
and the next test that would identify what this record cannot.
"""

from __future__ import annotations

import dataclasses
import math
from collections import Counter
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from driveid.errors import DriveIdError, IdentificationError, ParameterError
from driveid.identify._shape import ShapeVerdict, classify_record
from driveid.identify.core.estimate import Estimate
from driveid.io.record import Record
from driveid.signal.differentiate import lowpass_cutoff, position_noise_std

__all__ = ["identify_auto", "NEXT_TEST"]

#: What each test shape cannot identify, and the test (command) that would.
NEXT_TEST = {
    "free-decay": "static friction needs ramps from rest (driveid identify breakaway); J needs "
                  "a known mass or stiffness (--mass/--stiffness), a forced or a PHO test",
    "pho": "static friction is seen only where runs stick; ramps from rest (driveid identify "
           "breakaway) measure it directly",
    "sine": "static friction and the Stribeck curve need ramps (driveid identify breakaway) "
            "and constant-speed plateaus (driveid identify friction-map)",
    "step": "viscous friction at speed needs constant-speed plateaus (driveid identify "
            "friction-map)",
    "ramp": "kinetic and viscous friction at speed need plateaus (driveid identify "
            "friction-map); inertia needs a broadband or step test (driveid identify idim)",
    "plateaus": "inertia needs accelerations: a broadband or step test (driveid identify idim); "
                "static friction needs ramps from rest (driveid identify breakaway)",
    "broadband": "static friction needs ramps from rest (driveid identify breakaway); "
                 "backlash needs motor and load positions (driveid identify drive)",
    "operating": "a designed test identifies more with less doubt: PRBS or multisine "
                 "(driveid excite) for inertia and friction, ramps for static friction",
}


def _candidates(shape: str, records: list[Record], mass, stiffness) -> list[tuple[str, Callable]]:
    """Return ``(name, thunk)`` of the estimators that apply to a shape, best first."""
    from driveid.identify.free_decay import hilbert, logdec, output_error

    first = records[0]
    if shape == "free-decay":
        return [
            ("output-error", lambda: output_error.estimate_output_error(
                records, mass=mass, stiffness=stiffness)),
            ("hilbert", lambda: hilbert.estimate_hilbert(
                first.resampled_uniform(purpose="the Hilbert transform"), mass=mass)),
            ("peaks", lambda: logdec.estimate_log_decrement(
                [r.resampled_uniform(purpose="peak refinement") for r in records],
                mass=mass, stiffness=stiffness)),
        ]
    if shape == "pho":
        from driveid.identify.pho.peaks import estimate_pho_records
        from driveid.identify.pho.pho_fit import estimate_pho_output_error

        return [("pho-output-error", lambda: estimate_pho_output_error(records)),
                ("pho-peaks", lambda: estimate_pho_records(records))]
    if shape == "sine":
        from driveid.identify.forced.forced import estimate_forced_response

        return [("forced", lambda: estimate_forced_response(records, K_known=stiffness))]
    if shape == "step":
        from driveid.identify.friction.square_wave import estimate_square_wave
        from driveid.identify.friction.static_tests import estimate_step_response

        return [("square-wave", lambda: estimate_square_wave(records)),
                ("step", lambda: estimate_step_response(first))]
    if shape == "ramp":
        from driveid.identify.friction.breakaway import estimate_breakaway_sliding

        # a noisy force crosses zero at rest: ramps that stay below a third of the top
        # force are noise, not ramps
        top = max(float(np.max(np.abs(r.u))) for r in records if r.u is not None)
        v_break = _break_speed(records)
        return [("breakaway", lambda: estimate_breakaway_sliding(
            records, v_break=v_break, window=_rate_window(records, v_break),
            min_force=top / 3))]
    if shape == "plateaus":
        from driveid.identify.friction.friction_map import estimate_friction_map

        return [("friction-map", lambda: estimate_friction_map(
            records, models=("coulomb_viscous",), cutoff_hz=_speed_cutoff(records)).estimate)]
    if shape in ("broadband", "operating"):
        from driveid.identify.friction.idim import estimate_idim

        cutoff = _idim_cutoff(records)
        out = [("idim", lambda: estimate_idim(records, cutoff_hz=cutoff, parallel=True)),
               ("idim+spring", lambda: estimate_idim(records, cutoff_hz=cutoff,
                                                     regressors=("x",), parallel=True))]
        if shape == "operating":
            from driveid.identify.friction.friction_map import estimate_friction_map

            out.append(("friction-map", lambda: estimate_friction_map(
                records, models=("coulomb_viscous",),
                cutoff_hz=_speed_cutoff(records)).estimate))
        return out
    return []


def _idim_cutoff(records: Sequence[Record]) -> float:
    """Filter cut-off for IDIM [Hz]: 5x the band holding 95 % of the input's power.

    Twice-differentiated position noise grows as f²; a cut-off far above the excitation
    only adds noise to the acceleration regressor and biases J towards zero (errors in
    variables). Between 1 Hz and fs/5, and lowered further where the position noise would
    make the acceleration noise more than 5 % of its signal
    (:func:`driveid.signal.differentiate.lowpass_cutoff`).
    """
    from scipy.signal import welch

    tops = []
    for r in records:
        if r.u is None:
            continue
        freq, psd = welch(np.asarray(r.u, float) - float(np.mean(r.u)), fs=r.fs,
                          nperseg=int(min(r.n, 4096)))
        cum = np.cumsum(psd) / max(float(np.sum(psd)), 1e-300)
        tops.append(float(freq[min(int(np.searchsorted(cum, 0.95)), freq.size - 1)]))
    fs = min(r.fs for r in records)
    band = float(np.clip(5.0 * max(tops, default=fs), 1.0, 0.2 * fs))
    # and no higher than the position noise allows (x'' noise 5 % of the signal's); below
    # the decimation's band IDIM filters the force alike (parallel filtering), so a low
    # cut-off costs bandwidth, not bias
    return min(lowpass_cutoff(r.x, r.fs, highest=band) for r in records)


def _speed_cutoff(records: Sequence[Record]) -> float | None:
    """Low-pass for the friction map's speed [Hz]: fs/20, lower where the noise needs it.

    A test of force plateaus moves between them, so its acceleration has a signal; the
    cut-off whose x'' noise is 5 % of it keeps the speed's noise from hiding the approach to
    each plateau (which the map then mistakes for points; 5–15 % on f̄k at 1e-3 noise with
    fs/20, measured on simulated plateaus). None where the records carry a speed column.
    """
    if all(r.v is not None for r in records):
        return None
    return min(lowpass_cutoff(r.x, r.fs, highest=r.fs / 20.0) for r in records)


def _break_speed(records: Sequence[Record]) -> float:
    """Gross-sliding threshold: 5 % of the largest smoothed speed [m/s or rad/s]."""
    top = 0.0
    for r in records:
        x = np.asarray(r.x, float)
        w = max(int(0.02 * r.fs), 1)
        xs = np.convolve(x, np.ones(w) / w, mode="valid")
        if xs.size > 1:
            top = max(top, float(np.max(np.abs(np.diff(xs)))) * r.fs)
    return max(0.05 * top, 1e-12)


def _rate_window(records: Sequence[Record], v_break: float) -> float:
    """Window of the displacement rate [s]: its noise (√2 σ / window) a fifth of v_break.

    At least 10 samples (the estimator's default), at most a quarter second: a noisy
    position read over 10 samples crosses the sliding threshold at rest and puts the
    breakaway at the start of the ramp.
    """
    out = 0.0
    for r in records:
        sigma = position_noise_std(r.x)
        out = max(out, 10.0 / r.fs, min(5.0 * math.sqrt(2.0) * sigma / v_break, 0.25))
    return out


def _adequacy(est: Estimate) -> bool | None:
    ad = est.diagnostics.get("adequacy") if est.diagnostics else None
    if isinstance(ad, dict) and "adequate" in ad:
        return bool(ad["adequate"])
    return None


def _rank(item: tuple[int, str, Estimate]) -> tuple[int, int]:
    order, _, est = item
    verdict = _adequacy(est)
    # no verdict is not a better verdict than a failed one (friction-map runs no check)
    return (0 if verdict is True else 1, order)


def _bic(est: Estimate) -> float | None:
    """BIC ``n ln(RSS/n) + k ln n`` of a least-squares estimate that reports its residuals."""
    d = est.diagnostics or {}
    n, norm = d.get("n"), d.get("error_norm")
    if not (isinstance(n, int) and n > 0 and isinstance(norm, float) and norm > 0):
        return None
    k = sum(1 for p in est.params.values() if not p.fixed and math.isfinite(p.value))
    return n * math.log(norm**2 / n) + k * math.log(n)


def _nested_by_bic(ran, report):
    """Keep the nested IDIM variant (with or without a spring) of lower BIC; note both."""
    idims = [item for item in ran if item[1].startswith("idim") and _bic(item[2]) is not None]
    if len(idims) < 2:
        return ran
    best = min(idims, key=lambda item: _bic(item[2]))
    for _, name, est in idims:
        for row in report:
            if row["name"] == name:
                row["bic"] = _bic(est)
                row["kept_by_bic"] = name == best[1]
    return [item for item in ran if item not in idims or item is best]


def _disagreements(chosen: Estimate, name: str, others: list[tuple[str, Estimate]]) -> list[str]:
    out = []
    for other_name, other in others:
        for p, par in chosen.params.items():
            if p not in other.params or par.fixed or other.params[p].fixed:
                continue
            a, b = par, other.params[p]
            se = math.hypot(a.stderr if math.isfinite(a.stderr) else 0.0,
                            b.stderr if math.isfinite(b.stderr) else 0.0)
            # 3 combined standard errors, and 1 % (the methods define some quantities
            # slightly differently, e.g. Hilbert's instantaneous omega0 under friction)
            gap = abs(a.value - b.value)
            if se > 0 and math.isfinite(gap) and gap > 3 * se \
                    and gap > 0.01 * max(abs(a.value), abs(b.value)):
                out.append(f"{p}: {name} gives {a.value:.6g}, {other_name} {b.value:.6g} "
                           f"({abs(a.value - b.value) / se:.1f} combined standard errors apart)")
    return out


def identify_auto(records: Record | Sequence[Record], *, mass: float | None = None,
                  stiffness: float | None = None,
                  progress: Callable[[str], Any] | None = None) -> Estimate:
    """Classify the test shape of records, run the estimators that apply, return the best.

    Parameters
    ----------
    records : Record or sequence of Record
        One test (or several runs of one test): ``t`` [s], ``x`` [m or rad], ``u`` [N or
        N·m] where measured, ``meta`` with ``P``, ``D`` for PHO runs.
    mass : float, optional
        Known J [kg or kg·m²] (free decays: gives K, c, f_k in physical units).
    stiffness : float, optional
        Known K [N/m or N·m/rad].
    progress : callable, optional
        Called with each estimator's name before it runs.

    Returns
    -------
    Estimate
        The chosen estimator's result (its method, parameters [SI], standard errors,
        warnings) with ``diagnostics["auto"]``: ``shape``, ``evidence``, ``shapes`` (per
        record), ``chosen``, ``reason``, ``candidates`` (name, ok, adequate, parameters or
        error) and ``next_test``.

    Raises
    ------
    IdentificationError
        When no shape with an estimator is recognised, or every estimator fails (the
        message lists why each failed).
    ParameterError
        Both ``mass`` and ``stiffness``, or a non-positive one.

    Examples
    --------
    >>> from driveid.sim import OscillatorParams, simulate_free_decay
    >>> p = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, c_delta=0.1, fk_mean=0.07,
    ...                      fk_delta=0.03)
    >>> est = identify_auto(simulate_free_decay(p, x0=1.0, duration=20).record, mass=1.0)
    >>> est.diagnostics["auto"]["shape"], est.method, round(est.value("fk_mean"), 4)
    ('free-decay', 'output-error', 0.07)
    """
    recs = [records] if isinstance(records, Record) else list(records)
    if not recs:
        raise ParameterError("identify_auto needs at least one record; got none")
    if mass is not None and stiffness is not None:
        raise ParameterError("give the mass J or the stiffness K, not both (one fixes the other)")
    verdicts = [classify_record(r) for r in recs]
    shape, verdict = _majority(verdicts)
    candidates = _candidates(shape, recs, mass, stiffness)
    if not candidates:
        raise IdentificationError(
            "no test shape with an estimator was recognised: "
            + "; ".join(verdict.evidence or ("no evidence",))
            + ". Record the applied force (a force or current column) or a free decay")
    ran: list[tuple[int, str, Estimate]] = []
    report: list[dict[str, Any]] = []
    for order, (name, thunk) in enumerate(candidates):
        if progress is not None:
            progress(name)
        try:
            est = thunk()
        except (DriveIdError, np.linalg.LinAlgError, ValueError) as exc:
            report.append({"name": name, "ok": False, "error": str(exc)})
            continue
        ran.append((order, name, est))
        report.append({"name": name, "ok": True, "method": est.method,
                       "adequate": _adequacy(est),
                       "parameters": {k: [p.value, None if p.fixed else p.stderr]
                                      for k, p in est.params.items()}})
    if not ran:
        raise IdentificationError(
            f"the record looks like a {shape} test, but every estimator failed: "
            + "; ".join(f"{r['name']}: {r['error']}" for r in report))
    ran = _nested_by_bic(ran, report)
    ran.sort(key=_rank)
    _, name, chosen = ran[0]
    verdict_text = {True: "its residuals pass the adequacy checks",
                    None: "no candidate passes the adequacy checks; it is the first in order",
                    False: "no candidate passes the adequacy checks; it is the first in order"}
    reason = (f"{name} chosen: {verdict_text[_adequacy(chosen)]}"
              + ("" if len(candidates) == 1 else
                 f"; order of preference for a {shape} test: "
                 + ", ".join(n for n, _ in candidates)))
    warnings = list(chosen.warnings)
    if len({v.shape for v in verdicts}) > 1:
        warnings.append("the records do not all look like one test: "
                        + ", ".join(f"record {i}: {v.shape}" for i, v in enumerate(verdicts))
                        + f"; identified as {shape}")
    warnings += [f"methods disagree on {d}" for d in
                 _disagreements(chosen, name, [(n, e) for _, n, e in ran[1:]])]
    if _adequacy(chosen) is False:
        warnings.append(f"the {shape} model does not explain the record fully (see "
                        "diagnostics.adequacy); its error bars are widened accordingly")
    auto = {"shape": shape, "evidence": list(verdict.evidence),
            "shapes": [v.to_dict() for v in verdicts], "chosen": name, "reason": reason,
            "candidates": report, "next_test": NEXT_TEST.get(shape, "")}
    return dataclasses.replace(chosen, diagnostics={**dict(chosen.diagnostics), "auto": auto},
                               warnings=tuple(dict.fromkeys(warnings)))


def _majority(verdicts: list[ShapeVerdict]) -> tuple[str, ShapeVerdict]:
    counts = Counter(v.shape for v in verdicts)
    shape = max(counts, key=lambda s: (counts[s], -[v.shape for v in verdicts].index(s)))
    return shape, next(v for v in verdicts if v.shape == shape)
