"""Timeline repair and corrupted-burst detection (thesis App. B.3.1).

The thesis's acquisition PC produced two kinds of glitch: a *single* wrong timestamp every
20-30 files, which linear interpolation repairs, and 10-100 ms bursts of corrupted data
every ~100 files, which cannot be repaired: the run must be cropped or repeated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["TimelineCheck", "check_timeline", "find_corrupted_bursts"]


@dataclass(frozen=True)
class TimelineCheck:
    """Outcome of :func:`check_timeline`.

    Attributes
    ----------
    t : ndarray, shape (n,)
        The time vector [s], with single-sample glitches repaired: a repaired copy, or the
        given array itself when nothing was repaired (no 8 B a sample copy).
    repaired : tuple of int
        Indices whose timestamp was replaced by linear interpolation.
    problem : str or None
        Description of a defect that cannot be repaired, ``None`` when the timeline is usable.
    """

    t: np.ndarray
    repaired: tuple[int, ...]
    problem: str | None


def check_timeline(t: np.ndarray, *, max_jitter: float | None = 0.01) -> TimelineCheck:
    """Check that a time vector is increasing and uniform; repair isolated wrong timestamps.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times [s], n >= 3.
    max_jitter : float or None
        Largest accepted relative deviation of a sampling interval from the median interval
        [-]. ``None`` accepts any increasing, non-uniform timeline.

    Returns
    -------
    TimelineCheck
        Repaired timeline, the repaired indices and the unrepairable problem, if any.

    Notes
    -----
    Memory: one interval array (8 B a sample, for the median); every other pass runs over
    blocks of 65 536 intervals (issue 12: 10 M samples took five 80 MB temporaries).

    A timestamp ``t[i]`` is a single-sample glitch when the intervals on both sides of it are
    off but ``t[i+1] - t[i-1]`` is two nominal intervals (at the ends: one bad interval). Such a
    sample is given ``(t[i-1] + t[i+1]) / 2``; the data value is kept (App. B.3.1).

    Examples
    --------
    >>> check = check_timeline(np.array([0.0, 0.1, 0.5, 0.3, 0.4]))
    >>> check.repaired, float(check.t[2])
    ((2,), 0.2)
    """
    t = np.asarray(t, dtype=float)  # copied only when a timestamp is repaired
    n_int = t.size - 1
    # the median partitions a scratch array in place: one interval array is the largest
    # temporary (8 B a sample); every later pass runs over blocks of intervals
    nominal = float(np.median(np.diff(t), overwrite_input=True))
    if not nominal > 0:
        return TimelineCheck(
            t, (), f"time is not increasing: the median sampling interval is {nominal!r} s; "
            "sort the samples by time (oldest first) and drop duplicated timestamps"
        )
    # a non-uniform timeline (max_jitter=None) has no nominal interval to repair against
    tol = np.inf if max_jitter is None else max_jitter
    bad = np.zeros(n_int, bool)  # 1 B a sample
    if max_jitter is not None:
        for s, dt in _interval_blocks(t):
            bad[s:s + dt.size] = np.abs(dt - nominal) > tol * nominal
    repaired: list[int] = []
    for i in np.flatnonzero(bad).tolist():
        # interval i joins samples i and i+1: the culprit is the sample both bad intervals share
        for k in (i, i + 1):
            if k in repaired:
                break
            if 0 < k < len(t) - 1 and bad[k - 1] and bad[k]:
                span = t[k + 1] - t[k - 1]
                if abs(span - 2 * nominal) <= 2 * tol * nominal:
                    repaired.append(k)
                    break
            elif k == 0 and bad[0] and (len(bad) < 2 or not bad[1]):
                repaired.append(0)
                break
            elif k == len(t) - 1 and bad[-1] and (len(bad) < 2 or not bad[-2]):
                repaired.append(k)
                break
    if repaired:
        t = t.copy()
    for k in repaired:
        if k == 0:
            t[0] = t[1] - nominal
        elif k == len(t) - 1:
            t[k] = t[k - 1] + nominal
        else:
            t[k] = 0.5 * (t[k - 1] + t[k + 1])
    problem = None
    n_nonpos, first_nonpos = 0, -1
    worst, worst_jitter, worst_dt = -1, -np.inf, 0.0
    for s, dt in _interval_blocks(t):
        nonpos = np.flatnonzero(dt <= 0)
        if nonpos.size and first_nonpos < 0:
            first_nonpos = int(nonpos[0]) + s
        n_nonpos += nonpos.size
        if max_jitter is not None and not n_nonpos:
            jitter = np.abs(dt - nominal) / nominal
            j = int(np.argmax(jitter))
            if jitter[j] > worst_jitter:  # strict: the first of equal worst intervals
                worst, worst_jitter, worst_dt = j + s, float(jitter[j]), dt[j]
    if n_nonpos:
        i = first_nonpos
        kind = "duplicated" if t[i + 1] - t[i] == 0 else "decreasing"
        back = float(t[i] - t[i + 1])
        fix = "sort the samples by time and drop duplicated timestamps"
        if n_nonpos == 1 and back > 100 * float(nominal):
            # one jump back in an ordered record: sorting would scramble it (a clock set back
            # at the end of daylight saving time, fifth hostile campaign)
            fix = (f"the clock jumps back once, by {back:.6g} s"
                   + (" (daylight saving time ends: export the times with their UTC offset, "
                      "e.g. +01:00, or as seconds)" if abs(back - 3600.0) < 120.0 else
                      " (a clock reset?)")
                   + f"; sorting would scramble the record: add {back:.6g} s to the times "
                   "after the jump")
        problem = (
            f"time is {kind} at samples {i} and {i + 1} (t = {float(t[i])!r} s, "
            f"{float(t[i + 1])!r} s) and "
            f"{n_nonpos} interval(s) in all are not positive; {fix}"
        )
    elif max_jitter is not None:
        if worst_jitter > max_jitter:
            problem = (
                f"sampling is not uniform: interval {worst} is {worst_dt!r} s against a median "
                f"of {nominal!r} s ({100 * worst_jitter:.3g} % off, max_jitter={max_jitter}); "
                "resample the record to a uniform rate, or pass max_jitter=None to accept "
                "non-uniform sampling"
            )
    return TimelineCheck(t, tuple(sorted(repaired)), problem)


#: Intervals per block of the chunked passes (0.5 MB of float64 temporaries).
_BLOCK = 1 << 16


def _interval_blocks(t: np.ndarray, block: int = _BLOCK):
    """Yield ``(start, np.diff(t[start:start + block + 1]))``: the intervals in blocks."""
    for s in range(0, t.size - 1, block):
        yield s, np.diff(t[s:s + block + 1])


def find_corrupted_bursts(x: np.ndarray, *, factor: float = 20.0) -> list[tuple[int, int]]:
    """Find runs of samples that jump further than the signal can physically move.

    Parameters
    ----------
    x : ndarray, shape (n,)
        A measured signal, e.g. position [m or rad].
    factor : float
        A step counts as a jump when it exceeds ``factor`` times the 90th percentile of the
        non-zero step sizes [-] (robust while bursts are under 10 % of the record).

    Returns
    -------
    list of (int, int)
        Half-open index ranges ``[i0, i1)`` of corrupted samples.

    Notes
    -----
    A corrupted burst (App. B.3.1: 10-100 ms of garbage) enters and leaves with jumps of the
    order of the signal's range, while a physical position changes by at most ``v_max dt``
    per sample; a jump must also exceed 5 % of the signal's span (max - min). Jumps closer
    together than 200 samples are merged into one burst. Memory:
    the non-zero step sizes (at most 8 B a sample, for the quantile), filled and scanned
    in blocks.

    Examples
    --------
    >>> x = np.sin(np.linspace(0, 6, 1000)); x[500:520] = 5.0
    >>> find_corrupted_bursts(x)
    [(500, 520)]
    """
    x = np.asarray(x, dtype=float)
    if x.size - 1 < 10:
        return []
    # memory: the moving step sizes (at most 8 B a sample), filled block by block
    count = sum(int(np.count_nonzero(np.abs(step) > 0)) for _, step in _interval_blocks(x))
    if count < 10:
        return []
    moving = np.empty(count)
    filled = 0
    for _, step in _interval_blocks(x):
        step = np.abs(step)
        part = step[step > 0]
        moving[filled:filled + part.size] = part
        filled += part.size
    # quantile of the moving steps: a record that rests most of the time must not make every
    # motion look like a jump (partitioned in place: the scratch array is ours)
    threshold = factor * float(np.quantile(moving, 0.9, overwrite_input=True))
    del moving
    # and a twentieth of the signal's span: a burst enters with a jump of the order of the
    # range, while a short swing before a long noisy rest has steps 20x the noise's (the
    # simulator's own stick after half a swing was refused, fifth hostile campaign)
    finite = x[np.isfinite(x)]
    if finite.size:
        threshold = max(threshold, 0.05 * float(np.max(finite) - np.min(finite)))
    jumps = np.concatenate([np.flatnonzero(np.abs(step) > threshold) + s
                            for s, step in _interval_blocks(x)])
    if jumps.size == 0:
        return []
    bursts: list[tuple[int, int]] = []
    start = prev = int(jumps[0])
    for j in jumps[1:]:
        j = int(j)
        if j - prev > 200:
            bursts.append((start + 1, prev + 1))
            start = j
        prev = j
    bursts.append((start + 1, prev + 1))
    return [(i0, max(i1, i0 + 1)) for i0, i1 in bursts]
