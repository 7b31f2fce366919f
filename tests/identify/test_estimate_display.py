"""How an Estimate shows itself: repr, notebook HTML, pandas round trip, intervals."""

import math

import pytest

from driveid.errors import ParameterError
from driveid.identify.core.estimate import Estimate, Parameter


def _est():
    return Estimate(
        method="demo",
        params={"omega0": Parameter(4.0, 8.8e-8, "rad/s"), "J": Parameter(1.0, math.nan,
                                                                         "kg·m²", fixed=True),
                "fk_mean": Parameter(0.07, 1e-3, "N·m")},
        covariance={"names": ["omega0", "fk_mean"], "matrix": [[7.7e-15, 0.0], [0.0, 1e-6]]},
        warnings=("a warning <with markup>",))


def test_interval_is_the_normal_quantile_times_the_error():
    low, high = _est().interval("fk_mean", level=0.95)
    # z(0.975) = 1.959964 (closed form of the normal quantile, to 6 digits)
    assert (high - low) / 2 == pytest.approx(1.959964e-3, rel=1e-6)
    assert _est().interval("fk_mean", level=0.6827)[1] - 0.07 == pytest.approx(1e-3, rel=1e-3)
    assert all(math.isnan(v) for v in _est().interval("J"))  # given, not estimated
    with pytest.raises(ParameterError, match="level must lie in"):
        _est().interval("fk_mean", level=95)


def test_repr_is_a_readable_table_not_a_dump():
    text = repr(_est())
    assert text.startswith("<Estimate demo: 3 parameters, 1 warning(s)>")
    assert "(given)" in text and len(text.splitlines()) == 6


def test_notebook_html_shows_intervals_that_differ_and_escapes_text():
    html = _est()._repr_html_()
    assert "fixed (given)" in html and "&lt;with markup&gt;" in html
    # omega0 = 4 ± 8.8e-8: bounds printed with enough digits to differ
    assert "[3.999999828, 4.000000172]" in html  # 4 -+ 1.959964 * 8.8e-8


def test_to_pandas_round_trips_the_json():
    est = _est()
    frame = est.to_pandas()
    assert list(frame.index) == ["omega0", "J", "fk_mean"]
    assert frame.loc["J", "fixed"] and frame.attrs["method"] == "demo"
    assert Estimate.from_pandas(frame).to_dict() == est.to_dict()
