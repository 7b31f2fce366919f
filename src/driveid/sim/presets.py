r"""Plant presets: the thesis's mechanical positioning test bed and linear pendulum cart.

Every number below is either a *published* value quoted by the thesis (Tables 5.2 and
5.3, "published" columns) or an *assumption* of ours, marked as such in the docstring of
the preset. The thesis reports identification results, not a full simulation model: it
gives no feedback gains, no backlash gap and no shaft stiffness in numbers (App. C,
"Test Bed Counterbalance Modifications", is only a title in the text we have).

Presets carry a delayed PD loop (thesis §2.2.7, parametric harmonic oscillation) whose
delay is the published one; the gains are chosen by us so that a release from an initial
displacement gives a lightly damped pseudo-free oscillation of 2-3 Hz, with the
derivative gain above the negative damping ``P·delay`` that the delay adds.

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998, §2.1.4, §2.2.7,
       §4.3, §5.1, §5.2, Tables 5.2 and 5.3.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from driveid.errors import ParameterError
from driveid.sim.drive_types import (
    BacklashLink,
    BodyParams,
    DriveParams,
    PDFeedback,
    ShaftLink,
)

__all__ = [
    "TABLE_5_2_PUBLISHED",
    "TABLE_5_3_PUBLISHED",
    "PresetInfo",
    "PRESETS",
    "preset",
    "preset_units",
    "preset_testbed_a",
    "preset_testbed",
    "preset_pendulum_motor",
    "preset_pendulum_cart",
]

#: Thesis Table 5.2, "published" columns (values from its refs. [264], [367], [271]):
#: cumulative inertia ``J`` [kg·m²] (printed "N·m·s²"), viscous ``c_mean`` [N·m·s/rad]
#: (printed "Nms") and kinetic ``fk_mean`` [N·m] of the sections "A only", "A + B",
#: "A + B + C"; ``K`` is nil for all; ``delay`` [s] is published for "A only" only.
TABLE_5_2_PUBLISHED = {
    "A": {"delay": 13.77e-3, "J": 0.0115355, "K": 0.0, "c_mean": 0.0007457,
          "fk_mean": 0.109456},
    "A+B": {"J": 0.0150626, "K": 0.0, "c_mean": 0.0018657, "fk_mean": 0.1416169},
    "A+B+C": {"J": 0.0339399, "K": 0.0, "c_mean": 0.0029857, "fk_mean": 0.1711679},
}

#: Thesis Table 5.3, "published" columns (refs. [263], [355]): "motor only" mass ``J``
#: [kg], viscous ``c_mean`` [N·s/m], kinetic ``fk_mean`` [N], nil ``K``, ``c_delta`` and
#: ``fk_delta``, delay [s]; "motor + cart" publishes only the mass.
TABLE_5_3_PUBLISHED = {
    "motor": {"delay": 10.84e-3, "J": 1.4250, "K": 0.0, "c_mean": 0.3656, "c_delta": 0.0,
              "fk_mean": 3.7330, "fk_delta": 0.0},
    "motor+cart": {"J": 2.3900, "K": 0.0},
}


def preset_testbed_a() -> DriveParams:
    """Return body A of the test bed alone, under delayed PD feedback (rotational).

    Returns
    -------
    DriveParams
        One body with the published values of thesis Table 5.2, column "A only":
        ``J = 0.0115355`` kg·m², ``K = 0``, ``c_mean = 0.0007457`` N·m·s/rad,
        ``fk_mean = 0.109456`` N·m and the loop delay ``13.77`` ms.

    Notes
    -----
    Assumed (not in the thesis): ``c_delta = fk_delta = 0`` (no published asymmetry), static
    friction equal to kinetic, gains ``P = 5.0`` N·m/rad (about 3.3 Hz) and
    ``D = 0.1`` N·m·s/rad (net damping ``c_mean + D - P·delay`` about 0.032 N·m·s/rad,
    ζ ≈ 0.07). The published values predate the counterbalance modification of the
    backlash arms (thesis §5.1), which changes bodies A and B.

    Examples
    --------
    >>> preset_testbed_a().bodies[0].J
    0.0115355
    """
    a = TABLE_5_2_PUBLISHED["A"]
    body = BodyParams(J=a["J"], K=a["K"], c_mean=a["c_mean"], fk_mean=a["fk_mean"])
    return DriveParams(bodies=(body,), feedback=PDFeedback(P=5.0, D=0.1, delay=a["delay"]))


def preset_testbed() -> DriveParams:
    """Return the three-body test bed A–B–C: motor A, backlash to B, compliant shaft to C.

    Returns
    -------
    DriveParams
        Bodies from the differences of the cumulative published values of thesis Table 5.2
        ("A only", "A + B", "A + B + C"):

        ============  ===============  =====================  ===============
        body          J [kg·m²]        c_mean [N·m·s/rad]     fk_mean [N·m]
        ============  ===============  =====================  ===============
        A             0.0115355        0.0007457              0.109456
        B             0.0035271        0.00112                0.0321609
        C             0.0188773        0.00112                0.029551
        ============  ===============  =====================  ===============

        Feedback on A with the published delay 13.77 ms.

    Notes
    -----
    The order motor → backlash → compliance follows the lumped drive of thesis §2.1.4
    (Fig. 2.9: motor, transmission backlash, compliant tool). Assumed (the thesis gives no
    numbers): backlash A–B with ``gap_plus = gap_minus = 0.02`` rad, contact stiffness
    ``k = 100`` N·m/rad and damping ``c = 0.05`` N·m·s/rad, no tension; shaft B–C with
    ``k = 20`` N·m/rad (a B–C mode near 13 Hz) and ``c = 0.01`` N·m·s/rad; no asymmetry,
    static friction equal to kinetic; the delay of "A only" also for the whole chain
    (same loop hardware; Table 5.2 publishes none for A + B + C); gains ``P = 10.0``
    N·m/rad and ``D = 0.2`` N·m·s/rad (about 2.7 Hz on the whole inertia).

    Examples
    --------
    >>> [round(b.J, 7) for b in preset_testbed().bodies]
    [0.0115355, 0.0035271, 0.0188773]
    """
    t = TABLE_5_2_PUBLISHED
    sections = [t["A"], t["A+B"], t["A+B+C"]]
    bodies = []
    previous = {"J": 0.0, "c_mean": 0.0, "fk_mean": 0.0}
    for section in sections:
        bodies.append(BodyParams(J=section["J"] - previous["J"],
                                 c_mean=section["c_mean"] - previous["c_mean"],
                                 fk_mean=section["fk_mean"] - previous["fk_mean"]))
        previous = section
    links = (BacklashLink(gap_plus=0.02, gap_minus=0.02, k=100.0, c=0.05),
             ShaftLink(k=20.0, c=0.01))
    return DriveParams(bodies=tuple(bodies), links=links,
                       feedback=PDFeedback(P=10.0, D=0.2, delay=t["A"]["delay"]))


def preset_pendulum_motor() -> DriveParams:
    """Return the pendulum drive, motor only, as an equivalent linear mass (translational).

    Returns
    -------
    DriveParams
        One body with the published values of thesis Table 5.3, column "motor only":
        ``J = m = 1.425`` kg, ``K = 0``, ``c_mean = 0.3656`` N·s/m, ``c_delta = 0``,
        ``fk_mean = 3.733`` N, ``fk_delta = 0`` and the delay ``10.84`` ms. Units m, N.

    Notes
    -----
    Assumed: static friction equal to kinetic; gains ``P = 200`` N/m (about 1.9 Hz) and
    ``D = 3.0`` N·s/m (net damping ``c_mean + D - P·delay`` ≈ 1.2 N·s/m, ζ ≈ 0.04).

    Examples
    --------
    >>> preset_pendulum_motor().bodies[0].fk_mean
    3.733
    """
    m = TABLE_5_3_PUBLISHED["motor"]
    body = BodyParams(J=m["J"], K=m["K"], c_mean=m["c_mean"], c_delta=m["c_delta"],
                      fk_mean=m["fk_mean"], fk_delta=m["fk_delta"])
    return DriveParams(bodies=(body,), feedback=PDFeedback(P=200.0, D=3.0, delay=m["delay"]))


def preset_pendulum_cart() -> DriveParams:
    """Return the pendulum drive with the linear cart attached (translational).

    Returns
    -------
    DriveParams
        One body: the published "motor + cart" mass of thesis Table 5.3, ``J = m = 2.39``
        kg, ``K = 0``, with the motor's published friction (``c_mean = 0.3656`` N·s/m,
        ``fk_mean = 3.733`` N) and delay (10.84 ms). Units m, N.

    Notes
    -----
    Table 5.3 publishes no friction or delay for "motor + cart". Assumed: the motor's,
    since "the friction in that system was observed to be almost completely dominated by
    the motor friction" (thesis §4.3) — although the thesis's own identification (0.8043
    N·s/m, 7.934 N) finds more; static friction equal to kinetic; gains ``P = 300`` N/m
    (about 1.8 Hz) and ``D = 4.5`` N·s/m (net damping ≈ 1.6 N·s/m, ζ ≈ 0.03).

    Examples
    --------
    >>> preset_pendulum_cart().bodies[0].J
    2.39
    """
    m = TABLE_5_3_PUBLISHED["motor"]
    body = BodyParams(J=TABLE_5_3_PUBLISHED["motor+cart"]["J"], c_mean=m["c_mean"],
                      fk_mean=m["fk_mean"])
    return DriveParams(bodies=(body,), feedback=PDFeedback(P=300.0, D=4.5, delay=m["delay"]))


@dataclass(frozen=True, kw_only=True)
class PresetInfo:
    """A named preset.

    Attributes
    ----------
    description : str
        One line: what the plant is and where its numbers come from.
    units : {"rad", "m"}
        Rotational (rad, N·m) or translational (m, N) plant.
    build : callable
        Returns the :class:`~driveid.sim.drive.DriveParams`.
    """

    description: str
    units: str
    build: Callable[[], DriveParams]


#: Preset name -> :class:`PresetInfo`.
PRESETS = {
    "testbed-a": PresetInfo(
        description="test bed body A alone under delayed PD (Table 5.2 'A only', published)",
        units="rad", build=preset_testbed_a),
    "testbed": PresetInfo(
        description="test bed A-backlash-B-shaft-C (Table 5.2 published; gap, shaft assumed)",
        units="rad", build=preset_testbed),
    "pendulum-motor": PresetInfo(
        description="pendulum drive motor only, 1.425 kg (Table 5.3 'motor only', published)",
        units="m", build=preset_pendulum_motor),
    "pendulum-cart": PresetInfo(
        description="pendulum motor + cart, 2.39 kg (Table 5.3; motor friction assumed)",
        units="m", build=preset_pendulum_cart),
}


def _info(name: str) -> PresetInfo:
    if name not in PRESETS:
        raise ParameterError(f"unknown preset; use one of {sorted(PRESETS)}; got {name!r}")
    return PRESETS[name]


def preset(name: str) -> DriveParams:
    """Return the drive parameters of a named preset.

    Parameters
    ----------
    name : str
        A key of :data:`PRESETS` ("testbed-a", "testbed", "pendulum-motor",
        "pendulum-cart").

    Returns
    -------
    DriveParams
        The plant, with its delayed PD feedback.

    Raises
    ------
    ParameterError
        If ``name`` is not a preset.

    Examples
    --------
    >>> preset("pendulum-motor").feedback.delay
    0.01084
    """
    return _info(name).build()


def preset_units(name: str) -> str:
    """Return the position unit of a named preset: "rad" (rotational) or "m" (translational).

    Parameters
    ----------
    name : str
        A key of :data:`PRESETS`.

    Returns
    -------
    str
        "rad" or "m".

    Raises
    ------
    ParameterError
        If ``name`` is not a preset.
    """
    return _info(name).units
