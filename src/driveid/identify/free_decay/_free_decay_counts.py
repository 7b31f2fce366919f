r"""The number of half cycles before a free decay sticks, as the output-error fit treats it.

The count is discrete, so :mod:`driveid.identify.free_decay.output_error` fits the count the
kinetic friction allows from the start values and its neighbours (:func:`_candidates`),
rejects counts whose fitted reversals the kinetic band forbids (thesis 2.137-2.138: a
reversal inside ``|x + θk_delta| <= θk_mean`` would have stuck), refits until the fit's
own count agrees (:func:`_settle`), and averages the survivors with weights
``exp(-Δχ²/2)``, their spread entering the covariance (:func:`_combine`). ``problem`` is
the fit's ``_Problem`` (its ``t``, ``per`` and ``fit``).
"""

from __future__ import annotations

import numpy as np

from driveid.identify.free_decay._free_response import kinetic_stop_count, response


def _combine(candidates):
    """Average candidate fits with weights exp(-Δχ²/2); return mean, covariance, weights."""
    chi2 = np.array([c["chi2"] for c in candidates])
    w = np.exp(-0.5 * (chi2 - chi2.min()))
    w /= w.sum()
    mean = sum(wi * c["p"] for wi, c in zip(w, candidates, strict=True))
    cov = sum(wi * (c["cov"] + np.outer(c["p"] - mean, c["p"] - mean))
              for wi, c in zip(w, candidates, strict=True))
    return mean, cov, w



def _stop_counts(problem, p):
    counts = []
    for r, t in enumerate(problem.t):
        k = 5 + problem.per * r
        n, _ = kinetic_stop_count(p[:5], p[k], p[k + 1], float(t[-1]))
        counts.append(max(n, 1))
    return counts


def _forbidden(problem, p, counts):
    """Return True if a fitted reversal before the stop lies inside the kinetic band."""
    for r, (t, n_half) in enumerate(zip(problem.t, counts, strict=True)):
        k = 5 + problem.per * r
        _, _, rev = response(t, p[:5], p[k], p[k + 1], n_half, jacobian=False)
        inner = rev[1:-1, 1] if rev.shape[0] > 2 else np.empty(0)
        if np.any(np.abs(inner + p[4]) <= p[3]):
            return True
    return False


def _effective(problem, p, counts):
    """Stop counts truncated to the half cycles that start inside each record."""
    out = []
    for r, (t, n_half) in enumerate(zip(problem.t, counts, strict=True)):
        k = 5 + problem.per * r
        _, _, rev = response(t, p[:5], p[k], p[k + 1], n_half, jacobian=False)
        out.append(int(np.sum(rev[:-1, 0] < t[-1])))
    return tuple(out)


def _refine(problem, coarse, candidates):
    """Refit the plausible candidates of a decimated search on every sample."""
    if not candidates:
        return candidates
    rss_min = min(c["rss"] for c in candidates)
    s2 = rss_min / max(coarse.n - candidates[0]["p"].size, 1)
    out = []
    for c in candidates:
        # Δχ² grows with the sample count: 30 on the coarse data is certainly negligible
        if s2 > 0 and (c["rss"] - rss_min) / s2 > 30:
            continue
        sol = problem.fit(c["p"], c["counts"])
        if sol.status > 0 and not _forbidden(problem, sol.x, c["counts"]):
            out.append({"p": sol.x, "counts": c["counts"], "rss": float(2 * sol.cost),
                        "sol": sol})
    return out


def _settle(problem, p, max_iter=100):
    """Refit until the stop count the kinetic friction allows agrees with the fit's own."""
    counts = _stop_counts(problem, p)
    for _ in range(12):  # a peak start off by many half cycles walks ~2-6 per refit
        sol = problem.fit(p, counts, max_iter=max_iter)
        p = sol.x
        new = _stop_counts(problem, p)
        if new == counts:
            return p, counts, sol
        counts = new
    return p, counts, None


def _candidates(problem, p_best, counts0, settled=None, max_fits=30):
    """Fit stop counts around ``counts0`` until the best one's neighbours are all tried."""
    queue = [list(counts0)]
    for r in range(len(counts0)):
        for step in (-1, 1, -2):
            queue.append([c + step * (i == r) for i, c in enumerate(counts0)])
    tried, seen, out, refused = set(), set(), [], []
    while len(tried) < max_fits:
        if not queue and (out or refused):  # extend the search around the best so far
            # every count refused so far: walk on from the lowest RSS of the refused fits (a
            # tail below the encoder step hides the last half cycles, so the start count
            # can be ten or more off: Coulomb-dominated decays, issue 24)
            best = min(out or refused, key=lambda c: c["rss"])["counts"]
            queue = [[c + step * (i == r) for i, c in enumerate(best)]
                     for r in range(len(best)) for step in (-1, 1)]
            queue = [q for q in queue if tuple(q) not in tried and min(q) >= 1]
        if not queue:
            break
        counts = queue.pop(0)
        if tuple(counts) in tried or min(counts) < 1:
            continue
        tried.add(tuple(counts))
        if _effective(problem, p_best, counts) in seen:
            continue
        reuse = settled is not None and counts == list(counts0)
        sol = settled if reuse else problem.fit(p_best, counts)
        if sol.status <= 0 or not np.all(np.isfinite(sol.x)):
            continue
        if _forbidden(problem, sol.x, counts):
            refused.append({"counts": counts, "rss": float(2 * sol.cost)})
            continue
        key = _effective(problem, sol.x, counts)
        if key in seen:
            continue
        seen.add(key)
        out.append({"p": sol.x, "counts": counts, "rss": float(2 * sol.cost), "sol": sol})
    return out


def visible_half_cycles(y, factor=10.0):
    """Count the half cycles a record shows: reversals by more than ``factor`` x the noise.

    The noise is the robust spread of the second differences (white noise: sd·√6); the
    hysteresis is also at least 0.1 % of the span. Used only to word a refusal.
    """
    y = np.asarray(y, float)
    if y.size < 4:
        return 0
    d2 = np.diff(y, 2)
    noise = 1.4826 * float(np.median(np.abs(d2 - np.median(d2)))) / np.sqrt(6.0)
    span = float(np.max(y) - np.min(y))
    h = max(factor * noise, 1e-3 * span)
    if not h > 0:
        return 0
    count, direction, extreme, hi, lo = 0, 0, y[0], y[0], y[0]
    for value in y[1:]:
        if direction == 0:  # before the first move: from the highest or lowest so far
            hi, lo = max(hi, value), min(lo, value)
            if value < hi - h or value > lo + h:
                direction, extreme, count = (-1 if value < hi - h else 1), value, 1
        elif direction * (value - extreme) > 0:
            extreme = value
        elif direction * (extreme - value) > h:  # a reversal: the next half cycle
            direction, extreme, count = -direction, value, count + 1
    return count
