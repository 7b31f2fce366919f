"""Friction gallery: de Marchi (1998), §2.1.1, Figures 2.1–2.5.

Reproduces the thesis's friction figures with the models of ``driveid.models.friction``:

* Figure 2.1, Stribeck maps (2.2), (2.3), (2.5): mu_k = 1 N, mu_s = 4 N, nu = 0.5 N·s/m,
  v_s = 1 m/s; Bo–Pavelescu with delta = 0.5, 1, 2; Hess–Soom is (2.3) with mu_k = 0
  mapped through (2.4) with eta = 1 Pa·s, W = 1 N, E = 10 Pa, l = 1 m.
* Figure 2.2, rising static friction (2.6)–(2.8): mu_k = 1 N, mu_s(t_inf) = 4 N,
  gamma = 1 s, kappa = 1.
* Figure 2.3, frictional memory (2.12): Lorentzian (2.3) with mu_k = 1.5 N, mu_s = 4 N,
  nu = 0.5 N·s/m, v_s = 1 m/s, lag 0.25 s, velocity 1.5 + 1.3 sin(pi t) m/s (lag and
  velocity are not printed in the thesis; chosen here).
* Figure 2.4, presliding displacement (2.13)–(2.14): k_s = 1e4 N/m, breakaway
  4 N (positive) and 3 N (negative) (not printed in the thesis; chosen here).
* Figure 2.5, normal friction (2.1)–(2.2): eta = 1 Pa·s, E = 10 Pa (thesis), with
  mu_s = 4 N, c1 = 1, c2 = 0.2 N, l = 1 m and normal loads W = 1, 2, 5, 10, 20 N (chosen).

Usage: ``python examples/friction_gallery.py --out gallery/ [--force]``.
"""

import argparse
import functools
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from driveid.errors import OverwriteError  # noqa: E402
from driveid.models.friction import (  # noqa: E402
    BoPavelescuParams,
    HessSoomParams,
    LorentzianParams,
    bo_pavelescu_friction,
    hess_soom_friction,
    hess_soom_from_lorentzian,
    lorentzian_friction,
)
from driveid.models.friction_memory import (  # noqa: E402
    ArmstrongRisingParams,
    KatoRisingParams,
    PreslidingParams,
    lagged_friction,
    presliding_friction,
    rising_static_friction_armstrong,
    rising_static_friction_kato,
)

NAMES = [
    "fig2_1_stribeck_models.png",
    "fig2_2_rising_static_friction.png",
    "fig2_3_frictional_memory.png",
    "fig2_4_presliding.png",
    "fig2_5_normal_friction.png",
]


def figure_2_1(ax):
    v = np.linspace(0.0, 5.0, 501)[1:]
    lor = LorentzianParams(mu_k=1.0, mu_s=4.0, nu=0.5, v_s=1.0)
    ax.plot(v, lorentzian_friction(v, lor), label="Armstrong-Hélouvry et al. (2.3)")
    for delta in (0.5, 1.0, 2.0):
        bp = BoPavelescuParams(mu_k=1.0, mu_s=4.0, nu=0.5, v_s=1.0, delta=delta)
        ax.plot(v, bo_pavelescu_friction(v, bp), "--", label=f"Bo & Pavelescu (2.5), δ={delta:g}")
    hs = hess_soom_from_lorentzian(
        LorentzianParams(mu_k=0.0, mu_s=4.0, nu=0.5, v_s=1.0), eta=1.0, W=1.0, E=10.0, l=1.0
    )
    ax.plot(v, hess_soom_friction(v, hs), ":", label="Hess & Soom (2.2) via (2.4)")
    ax.set(
        xlabel="velocity [m/s]",
        ylabel="friction force [N]",
        ylim=(0, 4.5),
        title="Fig. 2.1  μk=1, μs=4, ν=0.5, v_S=1",
    )


def figure_2_2(ax):
    t = np.linspace(0.0, 10.0, 501)
    kato = KatoRisingParams(mu_k=1.0, mu_inf=4.0, gamma=1.0, kappa=1.0)
    arm = ArmstrongRisingParams(mu_inf=4.0, gamma=1.0)
    ax.plot(t, rising_static_friction_kato(t, kato), label="Kato / Howe (2.6)")
    ax.plot(t, rising_static_friction_armstrong(t, 1.0, arm), "--", label="Armstrong (2.7)")
    ax.plot(
        t,
        rising_static_friction_armstrong(t, 1.0, arm, form="exponential"),
        ":",
        label="Armstrong (2.8)",
    )
    ax.set(
        xlabel="dwell time [s]",
        ylabel="static friction [N]",
        ylim=(0, 4.5),
        title="Fig. 2.2  μk=1, μs=4, γ=κ=1",
    )


def figure_2_3(ax):
    lor = LorentzianParams(mu_k=1.5, mu_s=4.0, nu=0.5, v_s=1.0)
    dt = 1e-3
    t = np.arange(0.0, 4.0, dt)
    v = 1.5 + 1.3 * np.sin(np.pi * t)  # DC-biased, never reverses (as Hess & Soom)
    fmap = functools.partial(lorentzian_friction, params=lor)
    lagged = lagged_friction(v, dt, lag=0.25, friction=fmap)
    keep = t >= 2.0  # one period after the held-history start-up
    vs = np.linspace(0.2, 2.8, 261)
    ax.plot(vs, fmap(vs), color="0.6", label="static map (2.3)")
    ax.plot(v[keep], lagged[keep], label="lagged 0.25 s (2.12)")
    ax.set(
        xlabel="velocity [m/s]",
        ylabel="friction force [N]",
        title="Fig. 2.3  μk=1.5, μs=4, ν=0.5, v_S=1",
    )


def figure_2_4(ax):
    p = PreslidingParams(k_s=1e4, fs_plus=4.0, fs_minus=3.0)
    x = np.linspace(-8e-4, 8e-4, 801)
    ax.plot(x * 1e3, presliding_friction(x, p), label="k_s x, saturated at breakaway (2.13)")
    ax.plot(
        [-p.fs_minus / p.k_s * 1e3, p.fs_plus / p.k_s * 1e3],
        [-p.fs_minus, p.fs_plus],
        "o",
        label="breakaway x_s±, slope (2.14)",
    )
    ax.set(
        xlabel="presliding displacement [mm]",
        ylabel="friction force [N]",
        title="Fig. 2.4  k_s=1e4 N/m, μs+=4, μs−=3",
    )


def figure_2_5(ax):
    v = np.linspace(0.0, 10.0, 501)[1:]
    for W in (1.0, 2.0, 5.0, 10.0, 20.0):
        p = HessSoomParams(mu_s=4.0, c1=1.0, c2=0.2, eta=1.0, W=W, E=10.0, l=1.0)
        ax.plot(v, hess_soom_friction(v, p), label=f"W = {W:g} N")
    ax.set(
        xlabel="velocity [m/s]",
        ylabel="friction force [N]",
        ylim=(0, 4.5),
        title="Fig. 2.5  η=1 Pa·s, E=10 Pa (2.1)–(2.2)",
    )


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="gallery", help="output folder (default gallery/)")
    parser.add_argument("--force", action="store_true", help="overwrite existing PNGs")
    args = parser.parse_args(argv)
    out = Path(args.out)
    paths = [out / name for name in NAMES]
    existing = [str(p) for p in paths if p.exists()]
    if existing and not args.force:
        raise OverwriteError(
            f"refusing to overwrite {len(existing)} existing file(s); pass --force; "
            f"got {existing[0]}"
        )
    out.mkdir(parents=True, exist_ok=True)
    for path, draw in zip(
        paths, (figure_2_1, figure_2_2, figure_2_3, figure_2_4, figure_2_5), strict=True
    ):
        fig, ax = plt.subplots(figsize=(6.4, 4.4), layout="constrained")
        draw(ax)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
        fig.savefig(path, dpi=110)
        plt.close(fig)
        print(path)


if __name__ == "__main__":
    try:
        main()
    except OverwriteError as exc:
        sys.exit(str(exc))
