"""Figures of estimates: the log-decrement envelopes on a record whose equilibrium is offset."""

import numpy as np
import pytest

from driveid.identify.free_decay.logdec import estimate_log_decrement
from driveid.report.figures import _is_maximum, plot_log_decrement
from driveid.sim import OscillatorParams, simulate_free_decay


def test_alternating_extrema_are_split_by_neighbours_not_by_median():
    # all peaks above zero (an offset record): maxima and minima still alternate
    peaks = np.array([12.0, 8.5, 11.2, 8.9, 10.8, 9.2])
    assert _is_maximum(peaks).tolist() == [True, False, True, False, True, False]
    assert _is_maximum(-peaks).tolist() == [False, True, False, True, False, True]


@pytest.mark.parametrize("x0", [1.0, -1.0])
def test_envelopes_do_not_cross_on_an_offset_record(x0):
    params = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, c_delta=0.0, fk_mean=0.07,
                              fk_delta=0.0)
    rec = simulate_free_decay(params, x0=x0, duration=7.0, fs=1000.0).record  # 9 peaks
    shifted = rec.replace(x=rec.x + 5.0)  # encoder zero far from the spring's rest position
    est = estimate_log_decrement([shifted], mass=1.0)
    peak_x = np.asarray(est.data_used["peak_x"][0])
    if x0 < 0:
        # the case that broke the median split: more minima than maxima, so the median
        # lands on a minimum, which then joined the upper line
        assert peak_x.size % 2 == 1 and peak_x[0] < peak_x[1]
    fig = plot_log_decrement(est, record=shifted)
    dashed = [line for line in fig.axes[0].get_lines() if line.get_linestyle() == "--"]
    assert len(dashed) == 2
    upper, lower = (np.asarray(line.get_ydata()) for line in dashed)
    # every maximum lies above, every minimum below the Coulomb dead band about the rest
    # position 5 +- fk/K (after 7 s the swing, ~0.1 rad, is far wider than the band, 0.0044);
    # the old median split put the largest minimum on the upper line when minima outnumbered
    # maxima
    band = params.fk_mean / params.K
    assert upper.min() > 5.0 + band and lower.max() < 5.0 - band
    assert np.all(np.diff(upper) < 0) and np.all(np.diff(lower) > 0)
    import matplotlib.pyplot as plt

    plt.close(fig)


@pytest.mark.parametrize("n", [0, 1])
def test_one_or_no_peak(n):
    assert _is_maximum(np.ones(n)).tolist() == [True] * n
