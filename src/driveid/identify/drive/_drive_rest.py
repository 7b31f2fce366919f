"""Started at rest or moving: the nested test of a drive fit's estimated start velocities.

A record of a drive under its delayed PD loop that starts at rest gives a motor start
velocity fitted a few mrad/s off zero, and that velocity trades with the motor's viscous
friction and the loop's delay (correlation -0.97). On the two-body delayed-PD benchmark
(``benchmarks/bench_drive_fit.py --design two-body-pd``, seeds 0-15, quantised, one path)
the fit with the start velocities free covered J_1, c_1 and the delay in 12, 10 and 10 of
16 runs (sd of z 1.9-2.2), c_1's rms error 63 % of its value, and in 11 of the 16 it ended
*above* the fit with them held at 0, which it contains: it had not reached its minimum
along that trade. Held at 0 they covered 14 of 16 each (sd of z 1.2-1.3), c_1's rms error
8 %.

So every such fit is run again with the start velocities held at 0, along growing horizons
from the first fit's values (straight from its end, 14 of 16 went astray), and the two are
compared by their squared residuals over the noise (each channel's noise from second
differences, as the paths are compared): the start at rest is kept when freeing the ``k``
velocities lowers that sum by no more than the 95 % point of χ²(k) (a likelihood-ratio
test of the nested model); a narrow refusal fits the rest again from the other first
horizons (:func:`rest_retry`). A record that starts moving faster than the noise can hide
keeps its fitted velocities. Between the two (a start velocity of one or two of its
standard errors) the test keeps the rest, and the parameters that trade with the velocity
are then biased by up to about that many of their free-fit error bars: said in
docs/drive-fit.md; give the TOML's ``[run] v0`` when the start is known, or switch the test
off (``test_rest=False``, CLI ``--no-rest-test``). On 100 benchmark records, all started
at rest, the rest was kept on 89, and J_1, c_1 and the delay covered 0.83-0.85 (0.78-0.83
before): better, not yet calibrated (docs/drive-fit.md).
"""

from __future__ import annotations

from scipy.stats import chi2

from driveid.identify.drive._drive_pieces import squared_residual

__all__: list[str] = []

#: Level of the likelihood-ratio test above which a fitted start velocity is kept [-].
REST_LEVEL = 0.95
#: A refusal below this many times the test's limit fits the rest again from the other
#: first horizons (:func:`rest_retry`) [-].
REST_RETRY = 50.0


def rest_test(recs, moving_white: dict, rest_white: dict, n_fixed: int) -> dict:
    """Compare the fit with free start velocities against the one with them at 0.

    Parameters
    ----------
    recs : sequence of DriveRecord
        The fitted records.
    moving_white, rest_white : dict
        The two fits' per-channel residual summaries (``rms`` [channel unit]).
    n_fixed : int
        Start velocities held at 0 in the rest fit (bodies × records) [-].

    Returns
    -------
    dict
        ``delta_chi2``: the rest fit's squared residual over the noise minus the moving
        fit's [-] (negative where the moving fit stopped short of its minimum); ``limit``:
        the 95 % point of χ²(n_fixed) [-]; ``n_fixed``; ``at_rest``: whether the start at
        rest is kept.
    """
    delta = squared_residual(recs, rest_white) - squared_residual(recs, moving_white)
    limit = float(chi2.ppf(REST_LEVEL, n_fixed))
    return {"delta_chi2": delta, "limit": limit, "n_fixed": int(n_fixed),
            "at_rest": bool(delta <= limit)}


def rest_retry(resting, rest: dict, recs, moving_white: dict, first_kept: float,
               others, fit_at_rest):
    """Fit the start at rest from other first horizons; keep the lowest and test again.

    A narrow refusal (Δχ² under :data:`REST_RETRY` times the limit) of a record that
    started at rest was mostly a rest fit that ended in a poorer minimum than the free one
    (benchmark two-body PD, 100 records at rest: 20 refused at Δχ² 6-131, 17 of them with
    c_1 or the delay outside its interval); a record moving at the start is refused by
    thousands (0.3 rad/s: 6.8e4) and is not fitted again.

    Parameters
    ----------
    resting : tuple
        The rest fit so far (``whole_fit``'s stage, fit, base, warnings).
    rest : dict
        Its test (:func:`rest_test`).
    recs : sequence of DriveRecord
        The fitted records.
    moving_white : dict
        The fit with free start velocities, per channel (``rms`` [channel unit]).
    first_kept : float
        First horizon of the rest fit so far [s].
    others : sequence of float
        The other first horizons to try [s].
    fit_at_rest : callable
        ``fit_at_rest(first)``: the rest fit along growing horizons from ``first`` [s].

    Returns
    -------
    tuple
        The lowest rest fit and its test (``first_delta_chi2``: the first try's,
        ``first_horizons``: the horizons tried [s]).
    """
    best = squared_residual(recs, resting[1]["white"])
    for first in others:
        other = fit_at_rest(first)
        cost = squared_residual(recs, other[1]["white"])
        if cost < best:
            resting, best = other, cost
    again = rest_test(recs, moving_white, resting[1]["white"], rest["n_fixed"])
    again.update(first_delta_chi2=rest["delta_chi2"],
                 first_horizons=[float(first_kept)] + [float(f) for f in others])
    return resting, again
