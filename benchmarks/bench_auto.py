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
    # values: auto against each single method it ran, on every shape with a known truth
    # (free decays with the mass given, the others as they come)
    print("\nvalues: median |relative error| over records, auto's choice against each "
          "single method (the estimators auto ran, each as its own command would)")
    for shape in shapes:
        errs = collections.defaultdict(lambda: collections.defaultdict(list))
        for i in range(min(per_shape, 12)):
            rec, truth = simulate_shape_record(shape, rng=200_000 + 31 * i + shapes.index(shape))
            mass = truth["J"] if shape == "free-decay" else None
            try:
                est = identify_auto(rec, mass=mass)
            except Exception:  # noqa: BLE001 - a shape auto cannot identify is counted apart
                errs["(refused)"]["-"].append(1.0)
                continue
            chosen = est.diagnostics["auto"]["chosen"]
            for c in est.diagnostics["auto"]["candidates"]:
                if not c["ok"]:
                    continue
                for raw, (value, _) in c["parameters"].items():
                    name = _ALIAS.get(raw, raw)
                    if name in truth and truth[name] != 0 and name in _KEY:
                        e = abs(value / truth[name] - 1)
                        errs[c["name"]][name].append(e)
                        if c["name"] == chosen:
                            errs["auto"][name].append(e)
        for method, by_name in errs.items():
            text = ", ".join(f"{n} {np.median(e):.1e} ({len(e)})" for n, e in by_name.items())
            print(f"  {shape:<10} {method:<24} {text}")


#: the parameters compared (those every shape's truth has and the estimators name alike)
_KEY = ("J", "K", "fk_mean", "c_mean")
#: IDIM's names of the same quantities (symmetric model; k[x] the spring regressor)
_ALIAS = {"Fv": "c_mean", "Fc": "fk_mean", "k[x]": "K", "M": "J"}

if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 30)
