"""Reading-layer speed: driveid.io.read_record against plain pandas/numpy readers, same run.

Prints, per format, the time of ``read_record`` (format sniffing, units, validation,
sha256) divided by the time of the bare library call on the same file. Usage:
``python benchmarks/bench_reading.py [--rows 200000]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from driveid.io import read_record


def _best(func, repeat=3):
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        func()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rows", type=int, default=200_000)
    args = parser.parse_args()
    n = args.rows
    t = np.arange(n) * 1e-3
    x = np.exp(-0.1 * t) * np.cos(4 * t)
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        clean = folder / "clean.csv"
        np.savetxt(clean, np.column_stack([t, x]), delimiter=",", header="t [s],x [rad]",
                   comments="", fmt="%.12g")
        cassy = folder / "cassy.txt"
        rows = "\n".join(f"{a:.6f};{b:.10f}".replace(".", ",") for a, b in zip(t, x,
                                                                                strict=True))
        cassy.write_text("MCOSOFT\n\nZeit t / s;Weg / rad\n" + rows + "\n")
        parquet = folder / "d.parquet"
        pd.DataFrame({"t [s]": t, "x [rad]": x}).to_parquet(parquet)
        cases = [
            ("csv ','", clean, lambda: pd.read_csv(clean)),
            ("csv ';' decimal ','", cassy,
             lambda: pd.read_csv(cassy, sep=";", decimal=",", skiprows=2)),
            ("parquet", parquet, lambda: pd.read_parquet(parquet)),
        ]
        print(f"{'format':<22}{'read_record [ms]':>18}{'bare pandas [ms]':>18}{'ratio':>8}")
        for name, path, bare in cases:
            ours = _best(lambda p=path: read_record(p))
            base = _best(bare)
            print(f"{name:<22}{1e3 * ours:>18.1f}{1e3 * base:>18.1f}{ours / base:>8.2f}")


if __name__ == "__main__":
    main()
