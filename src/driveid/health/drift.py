"""Health of one axis against its machine type's blueprint: level test, CUSUM, verdict.

Two tests per monitored parameter, on the axis's identifications in time order:

* **level** — ``z = (x - nominal) / sqrt(spread² + max(0, se² - se_ref²))``: is the
  measurement outside what healthy axes of the type show, given the blueprint's spread
  *and* this measurement's standard error (only its excess over the blueprint's typical
  error is added, since that error is already inside ``spread``);
* **drift** — a two-sided, self-starting tabular CUSUM (Page 1954; Hawkins 1987) on the
  axis's own history: ``z_k = (x_k - m_k) / sqrt(r²(1 + 1/(k-1)) + max(0, se_k² - se_ref²))``
  with ``m_k`` the mean of all earlier identifications of the axis and ``r`` the
  blueprint's repeatability; these recursive residuals are independent N(0, 1) on a healthy
  axis (a fixed baseline from a few points would add a common error to every step, and the
  CUSUM would integrate it). ``S⁺_k = max(0, S⁺_{k-1} + z_k - k_ref)``,
  ``S⁻_k = max(0, S⁻_{k-1} - z_k - k_ref)``, started after ``baseline`` identifications.
  It sees a slow drift long before the level test, because it compares the axis with
  itself.

Thresholds are set for a stated false-alarm rate ``alpha`` per healthy axis-measurement,
split by Bonferroni over the monitored parameters and the two tests: the level test uses
the two-sided normal quantile of ``alpha/(2p)``; the CUSUM threshold ``h`` is the
``1 - alpha/(4p)`` quantile of ``max_k S_k`` over the horizon for healthy N(0, 1) data,
computed by a seeded Monte Carlo (so it bounds the rate at every measurement of the
horizon, and is conservative). ``watch`` uses ``watch_alpha``
the same way. The verdict is ``degraded`` if any test crosses its ``alpha`` threshold,
``watch`` if any crosses its ``watch_alpha`` threshold, else ``healthy``.

References
----------
.. [1] E. S. Page, "Continuous inspection schemes", Biometrika 41(1/2), 100-115, 1954.
       doi:10.1093/biomet/41.1-2.100
.. [2] D. M. Hawkins, "Self-starting CUSUM charts for location and scale", The
       Statistician 36(4), 299-316, 1987. doi:10.2307/2348827
.. [3] J. A. de Marchi, PhD thesis, RPI, 1998, §6.1 (track parameter drifts; monitor health).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.stats import norm

from driveid.errors import ConfigError

__all__ = ["ParameterHealth", "AxisHealth", "assess_axis", "cusum_threshold", "level_threshold"]

_VERDICTS = ("healthy", "watch", "degraded")


def level_threshold(alpha: float, n_parameters: int) -> float:
    """Two-sided |z| threshold of the level test for a false-alarm rate ``alpha``.

    Parameters
    ----------
    alpha : float
        False-alarm rate per healthy axis-measurement for all tests together [-].
    n_parameters : int
        Monitored parameters (Bonferroni share ``alpha / (2 n_parameters)``).

    Returns
    -------
    float
        Threshold on |z| [-].

    Examples
    --------
    >>> round(level_threshold(0.01, 5), 2)
    3.29
    """
    return float(norm.isf(alpha / (2 * n_parameters) / 2))


@functools.lru_cache(maxsize=64)
def cusum_threshold(alpha: float, n_parameters: int, *, baseline: int = 3, horizon: int = 12,
                    k_ref: float = 0.5, n_sim: int = 200_000) -> float:
    """CUSUM threshold ``h`` for a false-alarm rate ``alpha`` (seeded Monte Carlo).

    Parameters
    ----------
    alpha : float
        False-alarm rate per healthy axis-measurement for all tests together [-].
    n_parameters : int
        Monitored parameters; each one-sided CUSUM gets ``alpha / (4 n_parameters)``.
    baseline : int
        Identifications before the CUSUM starts (kept for the cache key; the self-starting
        residuals are N(0, 1) whatever it is).
    horizon : int
        Measurements after the baseline over which the rate holds.
    k_ref : float
        CUSUM allowance [standard deviations]; 0.5 is tuned to a one-sigma shift.
    n_sim : int
        Simulated healthy histories.

    Returns
    -------
    float
        Threshold on S⁺ and S⁻ [standard deviations].
    """
    rng = np.random.default_rng(20261123)
    share = alpha / (4 * n_parameters)
    worst = np.zeros(n_sim)
    s = np.zeros(n_sim)
    for _ in range(horizon):
        s = np.maximum(0.0, s + rng.standard_normal(n_sim) - k_ref)
        np.maximum(worst, s, out=worst)
    return float(np.quantile(worst, 1.0 - share))


@dataclass(frozen=True)
class ParameterHealth:
    """History and tests of one parameter of one axis.

    Attributes
    ----------
    name, unit : str
        Parameter and unit.
    times : ndarray of datetime64, shape (n,)
        Measurement times (UTC).
    values, stderr : ndarray, shape (n,)
        Identified values and standard errors [unit].
    z_level : ndarray, shape (n,)
        Level-test z against the blueprint [-].
    cusum_up, cusum_down : ndarray, shape (n,)
        CUSUM statistics (nan within the baseline) [-].
    baseline : float
        Mean of the axis's first ``baseline`` identifications [unit] (nan if too few
        measurements); changes are reported against it.
    verdicts : tuple of str
        Verdict of this parameter at each measurement.
    """

    name: str
    unit: str
    times: np.ndarray
    values: np.ndarray
    stderr: np.ndarray
    z_level: np.ndarray
    cusum_up: np.ndarray
    cusum_down: np.ndarray
    baseline: float
    verdicts: tuple[str, ...]


@dataclass(frozen=True)
class AxisHealth:
    """Verdict on one axis.

    Attributes
    ----------
    machine, axis : str
        The axis.
    verdict : str
        ``healthy``, ``watch`` or ``degraded`` at the latest measurement.
    reasons : tuple of str
        Which parameter, which test and by how much.
    parameters : mapping of str to ParameterHealth
        Per-parameter history and tests.
    verdicts : tuple of str
        The axis verdict at each measurement (using only the data up to it).
    thresholds : mapping
        ``z_level``, ``z_level_watch``, ``cusum``, ``cusum_watch`` and ``alpha``.
    n_failed : int
        Failed identifications of the axis (not tested, but reported).
    notes : tuple of str
        What the verdict does not cover, e.g. a drift test that did not run because the
        axis has no more identifications than the baseline.
    """

    machine: str
    axis: str
    verdict: str
    reasons: tuple[str, ...]
    parameters: dict[str, ParameterHealth]
    verdicts: tuple[str, ...]
    thresholds: dict[str, float] = field(default_factory=dict)
    n_failed: int = 0
    notes: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready summary with every parameter's history."""
        from driveid._json import to_jsonable

        return to_jsonable({
            "machine": self.machine, "axis": self.axis, "verdict": self.verdict,
            "reasons": list(self.reasons), "thresholds": self.thresholds,
            "n_failed": self.n_failed, "notes": list(self.notes),
            "verdicts": list(self.verdicts),
            "parameters": {n: {"unit": p.unit,
                               "times": [str(t) + "Z" for t in p.times],
                               "values": p.values, "stderr": p.stderr,
                               "z_level": p.z_level, "cusum_up": p.cusum_up,
                               "cusum_down": p.cusum_down, "baseline": p.baseline,
                               "verdicts": list(p.verdicts)}
                           for n, p in self.parameters.items()}})

    def plot(self) -> Any:
        """Draw every parameter's history, band and CUSUM; return the figure."""
        from driveid.health.figures import plot_axis_health

        return plot_axis_health(self)


def assess_axis(entries: Sequence[Any], blueprint: Any, *, alpha: float = 0.01,
                watch_alpha: float = 0.1, baseline: int = 3, k_ref: float = 0.5,
                horizon: int | None = None) -> AxisHealth:
    """Judge one axis's identifications against a blueprint.

    Parameters
    ----------
    entries : sequence of CatalogEntry
        The axis's catalogued identifications (any order; failures are counted, not tested).
    blueprint : Blueprint
        Its machine type's blueprint (:func:`driveid.health.make_blueprint`).
    alpha : float
        False-alarm rate of ``degraded`` per healthy axis-measurement [-], in (0, 0.5).
    watch_alpha : float
        The same for ``watch`` [-]; >= alpha.
    baseline : int
        Identifications before the CUSUM starts; their mean is the reference that changes
        are reported against.
    k_ref : float
        CUSUM allowance [standard deviations].
    horizon : int, optional
        Measurements after the baseline the CUSUM rate holds over (default: the history's
        length, at least 12).

    Returns
    -------
    AxisHealth
        The verdict, its reasons and every parameter's history.

    Raises
    ------
    ConfigError
        If no successful identification, entries of several axes, a monitored parameter
        missing, alpha outside its range, or baseline < 1.

    """
    if not (0 < alpha < 0.5 and alpha <= watch_alpha < 0.5):
        raise ConfigError(f"need 0 < alpha <= watch_alpha < 0.5; got alpha={alpha}, "
                          f"watch_alpha={watch_alpha}")
    if isinstance(baseline, bool) or not isinstance(baseline, int) or baseline < 1:
        # issue 28: baseline 0 divided by zero (exit 70); -1 took all but one as reference
        raise ConfigError(f"baseline must be an integer >= 1 (the identifications whose mean "
                          f"is the axis's reference; CLI --baseline); got {baseline!r}")
    axes = {(e.machine, e.axis) for e in entries}
    if len(axes) != 1:
        raise ConfigError(f"assess_axis takes the entries of one axis; got {sorted(axes)}")
    machine, axis = axes.pop()
    ok = sorted((e for e in entries if e.status == "ok"), key=lambda e: e.measured_at)
    n_failed = len(entries) - len(ok)
    if not ok:
        raise ConfigError(f"{machine}/{axis} has no successful identification to judge "
                          f"({n_failed} failed)")
    notes = []
    if len(ok) <= baseline:  # issue 28: 'healthy' with no drift test run, and no word
        most = (f"; baseline={len(ok) - 1} (CLI: --baseline) would run it" if len(ok) > 1
                else "")
        notes.append(
            f"the drift test (CUSUM) did not run: baseline={baseline} needs at least "
            f"{baseline + 1} successful identifications and the axis has {len(ok)}, so the "
            f"verdict rests on the level test against the blueprint alone{most}")
    names = list(blueprint.monitored)
    p = len(names)
    if horizon is None:
        horizon = max(12, len(ok) - baseline)
    thresholds = {
        "alpha": alpha, "watch_alpha": watch_alpha,
        "z_level": level_threshold(alpha, p), "z_level_watch": level_threshold(watch_alpha, p),
        "cusum": cusum_threshold(alpha, p, baseline=baseline, horizon=horizon, k_ref=k_ref),
        "cusum_watch": cusum_threshold(watch_alpha, p, baseline=baseline, horizon=horizon,
                                       k_ref=k_ref),
    }
    times = np.array([np.datetime64(e.measured_at, "s") for e in ok])
    results: dict[str, ParameterHealth] = {}
    reasons: list[tuple[int, float, str]] = []
    axis_level = np.zeros(len(ok), int)
    for name in names:
        missing = [e.measured_at for e in ok if name not in e.parameters]
        if missing:
            raise ConfigError(f"{machine}/{axis} has no {name!r} in the entries of {missing}; "
                              "the blueprint monitors it")
        bp = blueprint.parameters[name]
        x = np.array([e.parameters[name].value for e in ok], float)
        se = np.array([e.parameters[name].stderr for e in ok], float)
        se_ref = bp.se_ref if math.isfinite(bp.se_ref) else 0.0
        excess = np.maximum(0.0, np.nan_to_num(se, nan=0.0) ** 2 - se_ref**2)
        z = (x - bp.nominal) / np.sqrt(bp.spread**2 + excess)
        up = np.full(x.size, math.nan)
        down = np.full(x.size, math.nan)
        base = math.nan
        repeat = bp.repeatability if math.isfinite(bp.repeatability) else bp.spread
        if x.size > baseline:
            base = float(np.mean(x[:baseline]))
            s_up = s_down = 0.0
            for k in range(baseline, x.size):
                zk = (x[k] - np.mean(x[:k])) / math.sqrt(repeat**2 * (1 + 1 / k) + excess[k])
                s_up = max(0.0, s_up + zk - k_ref)
                s_down = max(0.0, s_down - zk - k_ref)
                up[k], down[k] = s_up, s_down
        level = np.zeros(x.size, int)
        for k in range(x.size):
            cus = max(np.nan_to_num(up[k]), np.nan_to_num(down[k]))
            if abs(z[k]) > thresholds["z_level"] or cus > thresholds["cusum"]:
                level[k] = 2
            elif abs(z[k]) > thresholds["z_level_watch"] or cus > thresholds["cusum_watch"]:
                level[k] = 1
        axis_level = np.maximum(axis_level, level)
        last = x.size - 1
        if level[last] > 0:
            cus_up, cus_down = np.nan_to_num(up[last]), np.nan_to_num(down[last])
            if max(cus_up, cus_down) / thresholds["cusum"] >= abs(z[last]) / thresholds["z_level"]:
                change = (x[last] - base) / abs(base) * 100 if base else math.nan
                text = (f"{name} {change:+.0f} % vs this axis's baseline {base:.4g} {bp.unit} "
                        f"(CUSUM {max(cus_up, cus_down):.1f}, threshold "
                        f"{thresholds['cusum']:.1f})")
                score = max(cus_up, cus_down) / thresholds["cusum"]
            else:
                change = (x[last] - bp.nominal) / abs(bp.nominal) * 100 if bp.nominal else math.nan
                text = (f"{name} {change:+.0f} % vs the blueprint's {bp.nominal:.4g} {bp.unit} "
                        f"(z = {z[last]:+.1f}, threshold {thresholds['z_level']:.1f})")
                score = abs(z[last]) / thresholds["z_level"]
            reasons.append((int(level[last]), score, f"{_VERDICTS[level[last]]}: {text}"))
        results[name] = ParameterHealth(
            name=name, unit=bp.unit, times=times, values=x, stderr=se, z_level=z,
            cusum_up=up, cusum_down=down, baseline=base,
            verdicts=tuple(_VERDICTS[v] for v in level))
    reasons.sort(key=lambda r: (-r[0], -r[1]))
    return AxisHealth(machine=machine, axis=axis, verdict=_VERDICTS[int(axis_level[-1])],
                      reasons=tuple(r[2] for r in reasons), parameters=results,
                      verdicts=tuple(_VERDICTS[v] for v in axis_level),
                      thresholds=thresholds, n_failed=n_failed, notes=tuple(notes))
