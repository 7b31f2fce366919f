"""``driveid pho run`` and ``driveid pho analyse``: PHO campaigns on a plant, and their analysis."""

from __future__ import annotations

import math
from pathlib import Path

import click

from driveid.commands import clean_errors
from driveid.commands._checks import SEED, PositiveFloat, bootstrap_options, parse_quantisation
from driveid.commands._output import emit, output_options, plot_of
from driveid.commands._progress import progress_bar
from driveid.commands._record_options import RecordOptions, record_options
from driveid.errors import ParameterError
from driveid.io.consistency import MAX_CAMPAIGN_RUNS, check_count
from driveid.io.manifest import read_manifest
from driveid.sim.presets import PRESETS, preset, preset_units

__all__ = ["pho_group", "pho_run_command", "pho_analyse_command", "preset_campaign_defaults"]


def _floats(text: str, option: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise click.BadParameter(f"expected comma-separated numbers like 5,6,7; got {text!r}",
                                 param_hint=option) from None
    if not values:
        raise click.BadParameter("give at least one value", param_hint=option)
    return values


def _round(value: float) -> float:
    """Round to one significant digit (a readable default)."""
    if value == 0:
        return 0.0
    return float(f"{value:.1g}")


#: Default campaign as fractions of the preset's own gains (help texts are built from these).
P_FACTORS = (0.4, 0.6, 0.8)
D_START_FACTOR = 0.3
D_STEP_FACTOR = 0.1
N_D_DEFAULT = 3


def preset_campaign_defaults(name: str) -> dict:
    """Return the default campaign of a preset, scaled from its own PD gains and friction.

    Parameters
    ----------
    name : str
        Preset name (:data:`driveid.sim.presets.PRESETS`).

    Returns
    -------
    dict
        ``P_values`` (P0·[0.4, 0.6, 0.8]) [N·m/rad or N/m], ``D_start`` (0.3·D0),
        ``D_step`` (0.1·D0) [N·m·s/rad or N·s/m], ``n_D`` (3), ``x0`` (50 fk/P0 rounded to
        one digit) [rad or m] and ``duration`` (5 s).

    Notes
    -----
    Gains below the preset's keep the delay's phase lag ``PΔ`` small and the net damping
    near zero, so runs ring long and c_mean (the small difference ``2Jσ - a``) is well
    resolved; the few settings whose oscillation grows hit the safety abort and are
    rejected. For "testbed-a": P = 2, 3, 4 N·m/rad, D = 0.03, 0.04, 0.05 N·m·s/rad,
    x0 = 1 rad; with 8000 counts/rev 12 of 18 runs are accepted and J, c_mean, fk_mean come
    back within 0.02 %, 1.1 %, 0.01 %.
    """
    params = preset(name)
    fb = params.feedback
    fk = sum(b.fk_mean for b in params.bodies)
    x0 = _round(50.0 * fk / fb.P) if fk > 0 else 1.0
    return {"P_values": [round(fb.P * f, 12) for f in P_FACTORS],
            "D_start": round(D_START_FACTOR * fb.D, 12),
            "D_step": round(D_STEP_FACTOR * fb.D, 12), "n_D": N_D_DEFAULT,
            "x0": x0, "duration": 5.0}


def _asymmetric(name: str, c_delta: float | None, fk_delta: float | None,
                fs_mean: float | None = None):
    """Return the preset's drive with asymmetric (and static) friction on the driven body."""
    import dataclasses

    params = preset(name)
    if c_delta is None and fk_delta is None and fs_mean is None:
        return params
    index = params.feedback.body if params.feedback is not None else 0
    changes = {k: v for k, v in (("c_delta", c_delta), ("fk_delta", fk_delta)) if v is not None}
    bodies = list(params.bodies)
    body = bodies[index]
    for option, delta, mean in (("--c-delta", c_delta, body.c_mean),
                                ("--fk-delta", fk_delta, body.fk_mean)):
        if delta is not None and abs(delta) > mean:
            # beyond the mean, one direction's friction would push the body
            raise ParameterError(
                f"{option} must lie within ±{mean:g} (the {name} preset's mean value), so that "
                f"friction opposes motion in both directions; got {delta:g}")
    if fk_delta is not None and not body.fs_delta:
        # the presets set static = kinetic friction; keep it so in each direction
        changes["fs_delta"] = fk_delta
    if fs_mean is not None:
        if not (math.isfinite(fs_mean) and fs_mean >= body.fk_mean):
            raise ParameterError(
                f"--fs-mean must be >= the kinetic friction fk_mean = {body.fk_mean:g} of the "
                f"{name} preset (static friction holds at least the kinetic); got {fs_mean:g}")
        changes["fs_mean"] = fs_mean
    bodies[index] = dataclasses.replace(body, **changes)  # validated by BodyParams
    return dataclasses.replace(params, bodies=tuple(bodies))


@click.group("pho")
def pho_group():
    """Parametric harmonic oscillation (PD-feedback) campaigns: run them, analyse them."""


@pho_group.command("run")
@click.option("--plant", "plant_name", type=click.Choice(sorted(PRESETS)), default="testbed-a",
              show_default=True, help="Simulated plant preset.")
@click.option("--out", "out", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="Campaign folder to create; refused if it already holds a campaign.")
@click.option("--P", "P_text", default=None,
              help="Proportional gains P_i [N·m/rad or N/m], comma-separated (default: the "
                   f"preset's P × {', '.join(f'{f:g}' for f in P_FACTORS)}).")
@click.option("--P-range", "P_range", type=(float, float, int), default=None,
              metavar="START STEP N", help="N equally stepped proportional gains.")
@click.option("--D-start", "D_start", type=float, default=None,
              help="First derivative gain [N·m·s/rad or N·s/m] (default: "
                   f"{D_START_FACTOR:g} × the preset's D).")
@click.option("--D-step", "D_step", type=float, default=None,
              help="Derivative gain step [N·m·s/rad or N·s/m] (default: "
                   f"{D_STEP_FACTOR:g} × the preset's D).")
@click.option("--n-D", "n_D", type=int, default=None,
              help=f"Number of derivative gains per P (default {N_D_DEFAULT}).")
@click.option("--x0", type=float, default=None,
              help="Initial displacement magnitude [rad or m]; each run goes from +x0 and -x0 "
                   "(default: 50·fk/P of the preset, one digit).")
@click.option("--duration", type=float, default=None, help="Length of each run [s] (default 5).")
@click.option("--fs", type=float, default=1000.0, show_default=True,
              help="Sampling rate [Hz].")
@click.option("--noise", type=float, default=0.0, show_default=True,
              help="Position noise standard deviation [rad or m].")
@click.option("--counts-per-rev", type=PositiveFloat(min=1.0), default=None,
              help="Encoder quantisation [counts/rev] (rotational presets).")
@click.option("--counts-per-metre", type=PositiveFloat(min=1.0), default=None,
              help="Encoder quantisation [counts/m] (translational presets).")
@click.option("--seed", type=SEED, default=None, help="Seed of the noise generator.")
@click.option("--abort-limit", type=float, default=None,
              help="Safety abort when |command| exceeds it [N·m or N] (default 2·max(P)·x0).")
@click.option("--min-peaks", type=int, default=5, show_default=True,
              help="Fewest oscillation peaks for an accepted run.")
@click.option("--K", "K", type=float, default=None,
              help="Stiffness known a priori, written to the manifest (e.g. 0).")
@click.option("--resume", is_flag=True,
              help="Continue an interrupted campaign in --out (same options): the runs "
                   "listed are kept, the others are run.")
@click.option("--max-runs", type=int, default=MAX_CAMPAIGN_RUNS, show_default=True,
              help="Most runs a campaign may plan (a guard against a mistyped --n-D).")
@click.option("--quiet", is_flag=True, help="No progress bar.")
@click.option("--c-delta", type=float, default=None,
              help="Make the driven body's viscous friction asymmetric: c_delta (signed) "
                   "[N·m·s/rad or N·s/m]; |c_delta| <= c_mean.")
@click.option("--fk-delta", type=float, default=None,
              help="Make the driven body's kinetic friction asymmetric: fk_delta (signed) "
                   "[N·m or N]; |fk_delta| <= fk_mean.")
@click.option("--fs-mean", type=float, default=None,
              help="Static friction of the driven body [N·m or N], >= its kinetic fk_mean "
                   "(default: equal, as the presets); the static band is fs_mean around "
                   "fk_delta (thesis 2.155a).")
@clean_errors
def pho_run_command(plant_name, out, P_text, P_range, D_start, D_step, n_D, x0, duration, fs,
                    noise, counts_per_rev, counts_per_metre, seed, abort_limit, min_peaks, K,
                    resume, max_runs, quiet, c_delta, fk_delta, fs_mean):
    """Run a PHO campaign: every (P, D) of the grid from +x0 and -x0, written to --out."""
    defaults = preset_campaign_defaults(plant_name)
    if P_text is not None and P_range is not None:
        raise click.UsageError("give --P or --P-range, not both")
    if P_text is not None:
        P_values = _floats(P_text, "--P")
    elif P_range is not None:
        start, step, n = P_range
        if n < 1:
            raise click.BadParameter(f"N must be >= 1; got {n}", param_hint="--P-range")
        P_values = [start + i * step for i in range(n)]
    else:
        P_values = defaults["P_values"]
    from driveid.experiment import SimulatedPlant, run_pho_campaign

    plant = SimulatedPlant(_asymmetric(plant_name, c_delta, fk_delta, fs_mean), noise_std=noise,
                           counts_per_rev=counts_per_rev, counts_per_unit=counts_per_metre,
                           seed=seed, units=preset_units(plant_name), name=plant_name)
    D_start = defaults["D_start"] if D_start is None else D_start
    D_step = defaults["D_step"] if D_step is None else D_step
    n_D = defaults["n_D"] if n_D is None else n_D
    x0 = defaults["x0"] if x0 is None else x0
    duration = defaults["duration"] if duration is None else duration
    n_runs = 2 * len(P_values) * n_D
    check_count(n_runs, max_runs, "runs in the campaign (2 x P values x D values)",
                override="--max-runs N")  # before the progress bar opens
    from driveid.experiment.pho import CSV_BYTES_PER_SAMPLE

    body = plant.params.bodies[plant.body]
    if max(P_values) > 0:
        # the loop rings at about sqrt((K + P)/J); at 5 Hz sampling of a 3 Hz loop every run
        # was rejected as "never oscillated" (fifth hostile campaign)
        f_loop = math.sqrt((body.K + max(P_values)) / body.J) / (2 * math.pi)
        if fs < 10 * f_loop:
            raise click.BadParameter(
                f"--fs {fs:g} Hz samples the loop's oscillation (about {f_loop:.3g} Hz at P = "
                f"{max(P_values):g}) fewer than 10 times a period: its peaks cannot be "
                f"found; give --fs {10 * f_loop:.3g} or more", param_hint="--fs")
    n_samples = n_runs * (duration * fs + 1)
    if n_samples > 5e7 and not quiet:  # long but feasible: say so before the silence
        click.echo(f"PHO campaign: {n_runs} runs of {duration:g} s at {fs:g} Hz, "
                   f"{n_samples:.3g} samples, about "
                   f"{n_samples * CSV_BYTES_PER_SAMPLE / 1e9:.3g} GB of CSV in {out}", err=True)
    with progress_bar(n_runs, "PHO runs", quiet=quiet, unit="run") as bar:
        campaign = run_pho_campaign(
            plant, P_values=P_values, D_start=D_start, D_step=D_step, n_D=n_D, x0=x0,
            duration=duration, fs=fs, out_dir=out, abort_limit=abort_limit,
            min_peaks=min_peaks, K=K, progress=lambda k, n, run: bar.update(1),
            resume=resume, max_runs=max_runs)
    units = plant.units
    click.echo(f"{'run':>4} {'P':>9} {'D':>9} {'x0 [' + units + ']':>10} {'peaks':>5} "
               f"{'settled [s]':>11}  result")
    for run in campaign.runs:
        a = run.assessment
        settled = "-" if a.settled_at is None else f"{a.settled_at:.3f}"
        result = "accepted" if a.accepted else f"rejected: {a.reason}"
        click.echo(f"{run.index:>4} {run.P:>9.4g} {run.D:>9.4g} {run.x0:>10.4g} "
                   f"{a.n_peaks:>5} {settled:>11}  {result}")
    click.echo(f"{len(campaign.accepted)} of {len(campaign.runs)} runs accepted; manifest: "
               f"{campaign.manifest_path}")


#: Most samples (all runs) the default ``--method auto`` fits whole: 6 runs of 3 s at 1 kHz
#: take ~1 s of processor time, 2.5x the peak analysis (benchmarks/bench_pho_coverage.py),
#: and the cost grows with the samples, so 500 000 take about 30 s (extrapolated).
OE_MAX_SAMPLES = 500_000

_RUN_META = ("P", "D", "x0", "x0_sign", "delay", "run_index", "units")


def _reread(records: list, record_opts: RecordOptions) -> list:
    """Read each run's file again with the record options, keeping the run's gains."""
    if record_opts == RecordOptions():
        return records
    out = []
    for rec in records:
        new = record_opts.read(rec.meta["source"])
        keep = {k: rec.meta[k] for k in _RUN_META if k in rec.meta and k != "units"}
        out.append(new.replace(meta=keep))
    return out


@pho_group.command("analyse")
@click.argument("path", type=click.Path(exists=True, path_type=Path))
@click.option("--delay", type=float, default=None,
              help="Loop delay [s], overriding the manifest's delay_s.")
@click.option("--estimate-delay", is_flag=True,
              help="Ignore the manifest's delay_s and estimate the delay from the campaign.")
@click.option("--uncompensated", is_flag=True,
              help="Analyse as if there were no delay (delay = 0), as the thesis's Table 5.2.")
@click.option("--K", "K", type=float, default=None,
              help="Known stiffness [N·m/rad or N/m] (e.g. 0), overriding the manifest's K.")
@click.option("--allow-outside", is_flag=True,
              help="Read record files the manifest names outside its own folder (only for a "
                   "manifest you trust).")
@click.option("--method", type=click.Choice(["auto", "oe", "peaks"]), default="auto",
              show_default=True,
              help="oe: whole-record fit of the delayed-PD loop to every sample of every run "
                   "(honest error bars on encoder records); peaks: per-run peak features "
                   "and the campaign equations; auto: oe, but peaks with --uncompensated, "
                   f"a negative K, above {OE_MAX_SAMPLES:,} samples in all, or if the oe "
                   "fit fails.")
@click.option("--static", "static", type=click.Choice(["auto", "kinetic", "band"]),
              default="auto", show_default=True,
              help="Static friction in the whole-record fit: auto fits static = kinetic and "
                   "a static band above kinetic (thesis 2.155a) and keeps the one the "
                   "information criterion prefers; kinetic or band imposes one.")
@click.option("--white-noise", is_flag=True,
              help="Whole-record fit without the AR noise model (white-noise error bars, "
                   "still widened when the residuals are not white).")
@bootstrap_options(50)
@record_options
@output_options
@clean_errors
def pho_analyse_command(path, delay, estimate_delay, uncompensated, K, allow_outside, method,
                        static, white_noise, quantisation, bootstrap, seed, record_opts,
                        output_opts):
    """Identify J, C, K and asymmetric friction from a campaign folder or manifest PATH.

    The record options apply to every run file (e.g. --t-start 0.2 drops a start transient,
    --position NAME picks the column of hand-written runs).
    """
    if sum([delay is not None, estimate_delay, uncompensated]) > 1:
        raise click.UsageError("give at most one of --delay, --estimate-delay, --uncompensated")
    manifest = read_manifest(path, allow_outside=allow_outside)
    records = _reread(manifest.load_records(), record_opts)
    if not records:
        raise ParameterError(
            f"no accepted run in {path}; every run was rejected (see the \"reason\" entries "
            "of the manifest); repeat the campaign with other gains or x0")
    if uncompensated:
        delay = 0.0
    elif delay is None and not estimate_delay:
        delay = manifest.delay_s
    if delay is not None and not (math.isfinite(delay) and delay >= 0):
        raise click.BadParameter(f"must be >= 0 [s]; got {delay}", param_hint="--delay")
    K_known = manifest.K if K is None else K
    from driveid.identify.pho.peaks import estimate_pho_records

    q = parse_quantisation(quantisation)
    n_samples = sum(r.n for r in records)
    # auto keeps the peaks where the simulated loop cannot follow: the thesis's delay-free
    # analysis, a negative spring, or more samples than a fit takes in reasonable time
    use_oe = method == "oe" or (method == "auto" and not uncompensated
                                and (K_known is None or K_known >= 0)
                                and n_samples <= OE_MAX_SAMPLES)
    peaks = estimate_pho_records(records, delay=delay, K_known=K_known, units=manifest.units)
    est = peaks
    if method == "auto" and not use_oe and n_samples > OE_MAX_SAMPLES and not uncompensated:
        est = peaks.with_warnings(
            f"{n_samples:,} samples in all: the peak analysis was used, whose error bars on "
            f"encoder records are not trustworthy; pass --method oe to fit every sample "
            f"(slow above {OE_MAX_SAMPLES:,}) or crop the runs with --t-end")
    if use_oe:
        from driveid.errors import IdentificationError, RecordError
        from driveid.identify.pho.pho_fit import estimate_pho_output_error

        try:
            with progress_bar(bootstrap, "bootstrap (encoder records)",
                              quiet=output_opts.quiet) as bar:
                est = estimate_pho_output_error(
                    records, delay=delay, K_known=K_known, units=manifest.units,
                    quantisation=q, bootstrap=bootstrap, rng=seed, start=peaks,
                    progress=lambda done, total: bar.update(1), static=static,
                    noise_model=not white_noise)
        except (IdentificationError, RecordError) as exc:
            if method == "oe":
                raise
            est = peaks.with_warnings(f"the whole-record fit failed ({exc}); these are the "
                                      "peak analysis's values")
    n_rej = len(manifest.runs) - len(records)
    how = ("uncompensated (delay 0)" if uncompensated else
           "delay estimated" if delay is None else f"delay {delay:g} s")
    label = "whole-record fit" if est.method == "pho-output-error" else "peak analysis"
    if est.method == "pho-output-error":
        d = est.diagnostics
        band = d.get("static_band")
        label += (f"; structure '{d['structure']}'"
                  + (" (band bracketed by the rest positions, no standard error)"
                     if band and band["chosen"] and not band["measured"] else "")
                  + f"; noise {d['noise_model']['kind']}; error bars: "
                  + d["adequacy"]["covariance"])

    def figure():
        return plot_of(est, records)

    emit(est, output_opts, records=records, figure=figure,
         header=f"{len(records)} accepted run(s), {n_rej} rejected; {how}; {label}")
