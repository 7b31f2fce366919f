"""Fleet batches (issue 28): several records per Dask task, catalogue written from a thread."""

from __future__ import annotations

import pytest

distributed = pytest.importorskip("distributed")

from driveid.catalog import Catalog, file_sha256  # noqa: E402
from driveid.errors import ConfigError  # noqa: E402
from driveid.fleet import identify_file, identify_files, identify_many  # noqa: E402
from driveid.sim.fleet import simulate_fleet  # noqa: E402


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    root = tmp_path_factory.mktemp("fleet") / "plant"
    simulate_fleet(root, n_axes=4, n_months=2, faulty_fraction=0.5, seed=3)
    return sorted(root.glob("*/*/20*.csv"))


def test_a_batch_is_its_single_records(fleet):
    """The batch task gives, record by record, what the one-record task gives."""
    files = fleet[:3]
    batch = identify_files(files, method_options={"mass": 1.0},
                           sha256=[file_sha256(f) for f in files])
    for path, outcome in zip(files, batch, strict=True):
        single = identify_file(path, method_options={"mass": 1.0})
        assert outcome["status"] == single["status"] == "ok"
        assert outcome["result"]["parameters"] == single["result"]["parameters"]
        assert outcome["result"]["inputs"][0]["sha256"] == file_sha256(path)


def test_batches_catalogue_every_record_once(fleet, tmp_path):
    bad = tmp_path / "plant" / "m9" / "x" / "2026-01-01.csv"
    bad.parent.mkdir(parents=True)
    bad.write_text("t,x\n0,1\n")
    files = [str(f) for f in fleet] + [str(bad)]
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        summary = identify_many(files, method_options={"mass": 1.0}, client=client,
                                catalog=tmp_path / "cat.sqlite", batch_size=3,
                                progress=False)
        # ceil(9 / 3) tasks; the bad file fails inside its batch and the rest go on
        assert summary.n_tasks == 3
        assert (summary.n_ok, summary.n_failed) == (8, 1)
        again = identify_many(files, method_options={"mass": 1.0}, client=client,
                              catalog=tmp_path / "cat.sqlite", progress=False)
        assert again.n_skipped == 9 and again.n_tasks == 0
    with Catalog(tmp_path / "cat.sqlite") as cat:
        assert cat.count() == 9


def test_batch_size_is_checked_before_submitting(fleet, tmp_path):
    with pytest.raises(ConfigError, match="batch_size must be"):
        identify_many([str(f) for f in fleet], catalog=tmp_path / "c.sqlite", batch_size=0)


def test_method_auto_recognises_free_decays_and_agrees_with_the_direct_fit(fleet):
    """``--method auto`` on a fleet of free decays: the shape is recognised and the chosen
    estimator is the whole-record fit, with the same values as ``method="output-error"``."""
    path = fleet[0]
    auto = identify_file(path, method="auto", method_options={"mass": 1.0})
    direct = identify_file(path, method="output-error", method_options={"mass": 1.0})
    assert auto["status"] == direct["status"] == "ok"
    diag = auto["result"]["diagnostics"]["auto"]
    assert diag["shape"] == "free-decay" and diag["chosen"] == "output-error"
    for name in ("K", "fk_mean", "c_mean"):
        a, d = auto["result"]["parameters"][name], direct["result"]["parameters"][name]
        # the same estimator on the same record: equal to solver accuracy
        assert a["value"] == pytest.approx(d["value"], rel=1e-6)


@pytest.mark.parametrize(("n", "workers"), [(1, 16), (7, 2), (320, 16), (1600, 16), (5000, 4)])
def test_guided_batches_shrink_to_single_records(n, workers):
    """Every record once, batches never growing, none above the cap, and the last wave
    (one record per worker at least) single records, so no worker waits a batch's time."""
    from driveid.fleet import _MAX_AUTO_BATCH, _batch_sizes

    sizes = _batch_sizes(n, workers, None)
    assert sum(sizes) == n
    assert all(a >= b for a, b in zip(sizes, sizes[1:], strict=False))
    assert max(sizes) <= _MAX_AUTO_BATCH
    assert sizes[-min(n, workers):] == [1] * min(n, workers)
    assert _batch_sizes(n, workers, 3) == [3] * (n // 3) + ([n % 3] if n % 3 else [])
