"""identify auto: confusion table of the test-shape classifier, and its values on free decays.

Usage: python benchmarks/bench_auto.py [records_per_shape=30]

Records: driveid.experiment.shapes, random plants, rates 200-2000 Hz, position noise 1e-4 to
1e-2 of the motion, encoders at random; a noisy force column where there is one. Prints the
confusion table (rows: true shape, columns: classified), the share right, the time per
classification, and on free decays the error of `identify auto` against each single method
(|error| in fk_mean relative to the truth, median over the records).
"""

import collections
import sys
import time
import warnings

import numpy as np

from driveid.experiment.shapes import SHAPE_GENERATORS, simulate_shape_record
from driveid.identify._shape import classify_record
from driveid.identify.auto import identify_auto


def main(per_shape: int = 30) -> None:
    warnings.simplefilter("ignore")
    shapes = list(SHAPE_GENERATORS)
    confusion = collections.defaultdict(collections.Counter)
    seconds = []
    for shape in shapes:
        for i in range(per_shape):
            rec, _ = simulate_shape_record(shape, rng=100_000 + 97 * i + shapes.index(shape))
            t0 = time.perf_counter()
            confusion[shape][classify_record(rec).shape] += 1
            seconds.append(time.perf_counter() - t0)
    cols = shapes + ["none"]
    print(f"{'true/got':<11}" + "".join(f"{c[:9]:>10}" for c in cols))
    for shape in shapes:
        print(f"{shape:<11}" + "".join(f"{confusion[shape][c]:>10}" for c in cols))
    right = sum(confusion[s][s] for s in shapes)
    total = per_shape * len(shapes)
    print(f"right: {right}/{total} = {100 * right / total:.1f} %; classification "
          f"{1e3 * np.median(seconds):.1f} ms median per record")
    # values: auto against each method alone, free decays with known mass
    errs = collections.defaultdict(list)
    for i in range(min(per_shape, 20)):
        rec, truth = simulate_shape_record("free-decay", rng=200_000 + i)
        est = identify_auto(rec, mass=truth["J"])
        errs["auto"].append(abs(est.value("fk_mean") / truth["fk_mean"] - 1))
        for c in est.diagnostics["auto"]["candidates"]:
            if c["ok"] and "fk_mean" in c["parameters"]:
                errs[c["name"]].append(abs(c["parameters"]["fk_mean"][0] / truth["fk_mean"] - 1))
    for name, e in errs.items():
        print(f"free decay fk_mean |relative error| {name:<13} median {np.median(e):.2e}, "
              f"max {np.max(e):.2e} ({len(e)} records)")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 30)
