"""The end-to-end demo: simulate a measured free decay, identify it, compare with the truth.

Plant: thesis Table 5.1, case 3 (J = 1 kg·m², K = 16 N·m/rad, c̄ = 0.3, Δc = 0.1 N·m·s/rad,
f̄k = 0.07, Δfk = 0.03 N·m) with static friction f̄s = 1.5 f̄k, released from +10 rad and from
-10 rad, sampled at 1 kHz by an 8000 counts/rev encoder. The two runs are identified
jointly (the thesis's FMixLR mixing) with J known by the whole-record output-error fit
(every sample; error bars by a re-quantising bootstrap) and, for comparison, by the
least-squares log decrement of the peaks and the thesis's closed forms, as printed and
corrected. The run folder also gets ``report.html``, a self-contained report.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

from driveid.identify.free_decay.logdec import estimate_log_decrement, estimate_log_decrement_thesis
from driveid.identify.free_decay.output_error import estimate_output_error
from driveid.io import write_record
from driveid.report.figures import plot_estimate, save_figure
from driveid.sim import OscillatorParams, measure, simulate_free_decay

__all__ = ["DEMO_PARAMS", "next_run_folder", "run_demo"]

#: The simulated plant of the demo (thesis Table 5.1 case 3, static friction 1.5 f̄k).
DEMO_PARAMS = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, c_delta=0.1, fk_mean=0.07,
                               fk_delta=0.03, fs_mean=0.105, fs_delta=0.03)


def next_run_folder(root: str | Path) -> Path:
    """Create and return ``root/run-NNN`` with the next free number (never reuses one).

    Parameters
    ----------
    root : str or Path
        Parent folder, created if missing.

    Returns
    -------
    Path
        The new, empty folder.
    """
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    numbers = [int(p.name[4:]) for p in root.glob("run-[0-9][0-9][0-9]*") if p.name[4:].isdigit()]
    number = max(numbers, default=0) + 1
    while True:
        folder = root / f"run-{number:03d}"
        try:
            folder.mkdir()
            return folder
        except FileExistsError:
            number += 1


def run_demo(out_root: str | Path = "driveid-demo", *,
             echo: Callable[[str], None] = print) -> dict:
    """Simulate, measure, identify and report; write records, JSON and a figure.

    Parameters
    ----------
    out_root : str or Path
        Parent folder; the demo writes into a new ``run-NNN`` folder inside it.
    echo : callable
        Receives the lines of the printed report.

    Returns
    -------
    dict
        ``folder`` (Path), ``truth`` and ``estimate`` (dicts of parameter values).
    """
    folder = next_run_folder(out_root)
    p = DEMO_PARAMS
    echo(f"driveid demo -> {folder}")
    echo("plant: J=1 kg·m², K=16 N·m/rad, c̄=0.3±0.1 N·m·s/rad, f̄k=0.07±0.03 N·m, "
         "f̄s=0.105 N·m; encoder 8000 counts/rev, 1 kHz, released from ±10 rad")
    records = []
    for sign, name in ((1, "pos"), (-1, "neg")):
        sim = simulate_free_decay(p, x0=10.0 * sign, duration=30.0, fs=1000.0)
        rec = measure(sim.record, counts_per_rev=8000)
        rec = rec.replace(meta={"x0_sign": sign, "plant": "table-5.1-case-3"})
        write_record(rec, folder / f"free_decay_{name}.csv")
        records.append(rec)
        end = (f"stuck at {sim.stuck_at:.2f} s" if sim.stuck_at is not None
               else "still moving at the end")
        echo(f"  run {name}: {sim.n_reversals} velocity reversals, {end}")
    est = estimate_output_error(records, mass=p.J, rng=0)  # every sample, bootstrap for counts
    peaks = estimate_log_decrement(records, mass=p.J)
    printed = estimate_log_decrement_thesis(records[0], corrected=False, mass=p.J)
    corrected = estimate_log_decrement_thesis(records[0], corrected=True, mass=p.J)
    truth = {"omega0": p.omega0, "K": p.K, "c_mean": p.c_mean, "c_delta": p.c_delta,
             "fk_mean": p.fk_mean, "fk_delta": p.fk_delta}
    echo("")
    echo(f"{'parameter':<10}{'truth':>10}{'output error (±1 s.e.)':>30}{'error':>10}"
         f"{'peaks':>12}{'thesis printed':>16}{'corrected':>12}")
    for name, true in truth.items():
        par = est[name]
        err = 100 * (par.value - true) / abs(true)
        echo(f"{name:<10}{true:>10.5g}{par.value:>18.6g} ± {par.stderr:<9.2g}{err:>9.3f}%"
             f"{peaks.value(name):>12.6g}{printed.value(name):>16.5g}"
             f"{corrected.value(name):>12.5g}")
    echo("")
    echo("units: omega0 rad/s, K N·m/rad, c N·m·s/rad, fk N·m; thesis columns use run 'pos'"
         " only (printed: first five peaks, with its errata)")
    from driveid.io import read_record
    from driveid.io.safe_write import atomic_write_text
    from driveid.report.html import write_report

    # provenance (path, SHA-256, rows, window, units) of the files the demo wrote
    written = [read_record(folder / f"free_decay_{name}.csv") for name in ("pos", "neg")]
    est = est.with_inputs(written)
    atomic_write_text(folder / "estimate.json",
                      json.dumps(est.to_dict(command=["driveid", "demo"]), indent=2))
    figure = save_figure(plot_estimate(est, record=records), folder / "free_decay_oe.png")
    report = write_report(
        [est], folder / "report.html", command=["driveid", "demo"],
        title="driveid demo: free decay of thesis Table 5.1 case 3, ± runs fitted jointly",
        figures=[("Both runs, measured peaks and the fitted envelopes", figure)])
    echo(f"wrote {folder / 'free_decay_pos.csv'}, {folder / 'free_decay_neg.csv'}, "
         f"{folder / 'estimate.json'}, {figure}, {report}")
    return {"folder": folder, "truth": truth,
            "estimate": {k: v.value for k, v in est.params.items()}}
