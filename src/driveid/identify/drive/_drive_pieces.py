"""Pieces of an open-loop drive record, each with its own initial state (second fit stage).

A free-floating drive that sticks and impacts is so sensitive to its parameters over a long
record that a whole-record output-error fit has no smooth minimum at the noise's scale (the
two-body backlash drive of ``benchmarks/bench_drive_fit.py --design two-body``: a random
1e-4 relative change of the parameters moves a 6 s record by 3-34 mrad rms against 0.2 mrad
of noise). Its estimates are close but its error bars are 10-2000 times short. Cut into
short pieces, each started from its own (estimated) state, every piece's output depends
smoothly on the parameters again, and the Gauss-Newton covariance of the pieces' fit is
calibrated (docs/drive-fit.md). The whole-record fit supplies the start: its parameters and,
for each piece, the better of two start states: the state its simulation passes through at
the piece's first sample, or the state the piece's own measured channels show there
(:func:`measured_states`).
"""

from __future__ import annotations

import numpy as np

from driveid.identify.drive._drive_covariance import _channel_noise
from driveid.identify.drive._drive_model import DriveRecord, channel_index
from driveid.sim.drive_types import BacklashLink, DriveParams

__all__: list[str] = []

AUTO_PIECE = 0.5  # piece length of the automatic second stage [s] (docs/drive-fit.md)
# a whole-record residual this many times the channel's noise (second differences) means
# the fit did not reach the noise: the automatic second stage runs (docs/drive-fit.md)
NOISE_RATIO = 1.5


def cut_pieces(recs, length: float) -> tuple[list[DriveRecord], list[tuple[int, int]]]:
    """Cut every record into consecutive pieces of ``length`` seconds.

    Parameters
    ----------
    recs : sequence of DriveRecord
        The records, uniform time [s].
    length : float
        Piece length [s]; a remainder shorter than half a piece joins the last piece.

    Returns
    -------
    pieces : list of DriveRecord
        The pieces, each with its time from 0 [s].
    origin : list of (int, int)
        Per piece: the index of its record and of its first sample.
    """
    pieces, origin = [], []
    for r, rec in enumerate(recs):
        n = rec.t.size
        m = max(int(round(length * rec.fs)), 20)
        firsts = list(range(0, n - 1, m))
        if len(firsts) > 1 and n - 1 - firsts[-1] < m // 2:
            firsts.pop()
        for k, a in enumerate(firsts):
            b = n if k == len(firsts) - 1 else a + m + 1
            pieces.append(DriveRecord(
                t=rec.t[a:b] - rec.t[a], u=None if rec.u is None else rec.u[a:b],
                channels={c: y[a:b] for c, y in rec.channels.items()}, meta=rec.meta))
            origin.append((r, a))
    return pieces, origin


def piece_states(problems, thetas, origin) -> list[tuple[np.ndarray, np.ndarray]]:
    """Return the simulated state at each piece's first sample (the pieces' start states).

    Parameters
    ----------
    problems : sequence of DriveProblem
        The whole-record fit's problems, one per record.
    thetas : sequence of ndarray
        Per record, its scaled parameter vector ``z`` at the whole-record fit's optimum [-].
    origin : sequence of (int, int)
        Per piece: record index and first sample (from :func:`cut_pieces`).

    Returns
    -------
    list of (ndarray, ndarray), shape (n_bodies,) each
        Positions [rad or m] and velocities [rad/s or m/s] per piece.
    """
    from driveid.sim.batch import simulate_drive_batch

    runs = []
    for prob, z in zip(problems, thetas, strict=True):
        params, x0, v0 = prob.build(z)
        runs.append(simulate_drive_batch([params], duration=prob.duration, fs=prob.fs,
                                         x0=x0[None, :], v0=v0[None, :],
                                         torque=prob.torque, parallel=False)[0])
    return [(runs[r].x[:, a].copy(), runs[r].v[:, a].copy()) for r, a in origin]


#: Samples at the start of a piece that its measured start state is read from (a quadratic
#: in time, least squares: 20 ms at 1 kHz, short beside the bodies' motion, long enough to
#: average the noise and the encoder's steps down).
START_SAMPLES = 21


def measured_states(pieces, fallback, locked=None) -> list[tuple[np.ndarray, np.ndarray]]:
    """Return each piece's start state as its measured channels show it.

    The whole-record fit can sit in a poor minimum whose simulation drifts from the record;
    the states it passes through may then put a load on the wrong side of its gap, where
    the pieces' fit cannot follow. A measured position reads the gap directly. As the
    second candidate of each piece's start (the better kept) it took the benchmark's
    two-body drive from 87 to 92 of 100 runs within 5 % (friction 10 %), seeds 20, 23, 38
    among them; it does not help where the pieces' objective itself has the poor minimum
    (seeds 35 and 60: c_2 -17 % and -34 %; docs/drive-fit.md).

    Parameters
    ----------
    pieces : sequence of DriveRecord
        The pieces (from :func:`cut_pieces`).
    fallback : sequence of (ndarray, ndarray)
        Per piece the simulated start state, kept for every body without a measured channel.
    locked : sequence of bool, optional
        Per body, locked (kept at its fallback: a locked body starts at rest).

    Returns
    -------
    list of (ndarray, ndarray)
        Positions [rad or m] and velocities [rad/s or m/s]: a measured position's quadratic
        fit over its first :data:`START_SAMPLES` samples at the piece's first sample, its slope
        there (or a measured velocity's linear fit) for the velocity.
    """
    out = []
    for piece, (x0, v0) in zip(pieces, fallback, strict=True):
        x0, v0 = x0.copy(), v0.copy()
        m = min(START_SAMPLES, piece.t.size)
        t = piece.t[:m] - piece.t[0]
        velocity_measured = set()
        for ch, y in piece.channels.items():
            kind, body = channel_index(ch)
            if body >= x0.size or m < 4 or (locked is not None and locked[body]):
                continue
            if kind == "x":
                c = np.polyfit(t, y[:m], 2)
                x0[body] = c[2]
                if body not in velocity_measured:
                    v0[body] = c[1]
            else:
                v0[body] = np.polyfit(t, y[:m], 1)[1]
                velocity_measured.add(body)
        out.append((x0, v0))
    return out


def piece_costs(fit, z: np.ndarray, noise: dict) -> np.ndarray:
    """Per piece, the sum of squared residuals in units of each channel's noise [-]."""
    return np.array([sum(float(np.sum((res[c] / noise[ch]) ** 2))
                         for c, ch in enumerate(prob.channels))
                     for prob, res in zip(fit.problems, fit.raw_residuals(z), strict=True)])


def _channel_ratios(recs, white: dict):
    """Yield each fitted channel's samples and residual rms over its noise [-]."""
    for r, rec in enumerate(recs):
        for ch, y in rec.channels.items():
            key = ch if len(recs) == 1 else f"{ch}@{r + 1}"
            if key in white:
                yield y.size, white[key]["rms"] / _channel_noise(y)


def _noise_ratio(recs, white: dict) -> float:
    """Largest ratio of a channel's residual rms to its noise from second differences [-]."""
    return max((ratio for _, ratio in _channel_ratios(recs, white)), default=0.0)


def squared_residual(recs, white: dict) -> float:
    """Sum over every fitted channel's samples of (residual / noise)² [-]."""
    return float(sum(size * ratio ** 2 for size, ratio in _channel_ratios(recs, white)))


def _path_cost(recs, white: dict) -> float:
    """Squared residual over the noise's, pooled over every channel's samples [-]."""
    n = sum(size for size, _ in _channel_ratios(recs, white))
    return squared_residual(recs, white) / max(n, 1)


def _piece_length(pieces: float | None, open_loop: bool, recs, white: dict,
                  drive: DriveParams) -> float:
    """Piece length of the second stage [s], 0 for none (see ``pieces`` of estimate_drive).

    Automatic: an open-loop fit of a record longer than two pieces, of a drive with
    backlash (a load that flies in the gap and impacts) or whose residual is not white or
    stays above the noise (:data:`NOISE_RATIO`). Neither check alone finds the backlash
    drive's trouble: its fits reach the noise with white residuals and still miss by
    hundreds of standard errors (benchmark two-body drive: 12 of 30 white, 2 of 10 within
    1.1 times the noise, missing by 800 and 3700 standard errors; docs/drive-fit.md).
    """
    if pieces is None:
        longest = max(float(r.t[-1] - r.t[0]) for r in recs)
        poor = (any(isinstance(link, BacklashLink) for link in drive.links)
                or not all(w["white"] for w in white.values())
                or _noise_ratio(recs, white) > NOISE_RATIO)
        return AUTO_PIECE if open_loop and poor and longest > 2.0 * AUTO_PIECE else 0.0
    return float(pieces)
