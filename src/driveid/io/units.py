"""Units of measured traces: header spellings and conversion to SI at the reading edge.

A column header carries its unit in one of the spellings that real exports use::

    x [deg]     x (deg)     x / deg     x in deg     Weg &b_A1 / rad     Zeit t / s

:func:`split_header` separates the name from the unit; :func:`to_si` gives the SI unit and
factor of a unit for a record column (``t``, ``x``, ``v``, ``u``). Inside driveid everything
is SI (rad, m, s, N, N·m); other units exist only in files and on the command line.
Volts and amperes are not physical quantities of the drive: they enter only through an
explicit scale (``--scale u=200`` for 200 N per V), never by guessing a gain.
"""

from __future__ import annotations

import math
import re

from driveid.errors import FileFormatError

__all__ = ["UNIT_CONVERSIONS", "ELECTRICAL_UNITS", "split_header", "normalise_unit", "to_si",
           "wrong_role", "known_units", "known_unit"]

_DEG = math.pi / 180.0
_INCH = 0.0254
_FOOT = 0.3048
_LBF = 4.4482216152605
_OZF = _LBF / 16.0

#: Record column -> unit -> (SI unit, factor to SI). Counts are handled by :func:`to_si`.
UNIT_CONVERSIONS: dict[str, dict[str, tuple[str, float]]] = {
    "t": {"s": ("s", 1.0), "ms": ("s", 1e-3), "µs": ("s", 1e-6), "ns": ("s", 1e-9),
          "min": ("s", 60.0), "h": ("s", 3600.0)},
    "x": {"rad": ("rad", 1.0), "mrad": ("rad", 1e-3), "deg": ("rad", _DEG),
          "mdeg": ("rad", 1e-3 * _DEG),
          "rev": ("rad", 2 * math.pi), "m": ("m", 1.0), "cm": ("m", 1e-2), "mm": ("m", 1e-3),
          "µm": ("m", 1e-6), "nm": ("m", 1e-9), "in": ("m", _INCH), "ft": ("m", _FOOT)},
    "v": {"rad/s": ("rad/s", 1.0), "deg/s": ("rad/s", _DEG), "rpm": ("rad/s", math.pi / 30),
          "rev/s": ("rad/s", 2 * math.pi), "m/s": ("m/s", 1.0), "mm/s": ("m/s", 1e-3),
          "µm/s": ("m/s", 1e-6), "m/min": ("m/s", 1 / 60), "mm/min": ("m/s", 1e-3 / 60),
          "in/s": ("m/s", _INCH), "in/min": ("m/s", _INCH / 60), "ft/s": ("m/s", _FOOT),
          "ft/min": ("m/s", _FOOT / 60)},
    "u": {"N": ("N", 1.0), "kN": ("N", 1e3), "mN": ("N", 1e-3), "lbf": ("N", _LBF),
          "kip": ("N", 1e3 * _LBF), "ozf": ("N", _OZF), "N·m": ("N·m", 1.0),
          "mN·m": ("N·m", 1e-3), "kN·m": ("N·m", 1e3), "N·mm": ("N·m", 1e-3),
          "N·cm": ("N·m", 1e-2), "oz·in": ("N·m", _OZF * _INCH),
          "lbf·in": ("N·m", _LBF * _INCH), "lbf·ft": ("N·m", _LBF * _FOOT)},
}

#: Electrical units: accepted only with an explicit ``scale`` to the physical quantity.
ELECTRICAL_UNITS = ("V", "mV", "A", "mA")

_SPELLINGS = {
    # time
    "sec": "s", "secs": "s", "second": "s", "seconds": "s", "msec": "ms", "us": "µs",
    "μs": "µs", "minute": "min", "minutes": "min", "hr": "h",
    # angle and length
    "radian": "rad", "radians": "rad", "°": "deg", "degree": "deg", "degrees": "deg",
    "grad": "deg", "revs": "rev", "revolution": "rev", "revolutions": "rev", "turn": "rev",
    "millidegree": "mdeg", "millidegrees": "mdeg",
    "turns": "rev", "r": "rev", "um": "µm", "μm": "µm", "micron": "µm", "microns": "µm",
    "inch": "in", "inches": "in", '"': "in", "foot": "ft", "feet": "ft", "metre": "m",
    "meter": "m", "millimetre": "mm", "millimeter": "mm",
    # velocity
    "°/s": "deg/s", "1/min": "rpm", "u/min": "rpm", "r/min": "rpm", "rev/min": "rpm",
    "min^-1": "rpm", "min-1": "rpm", "rps": "rev/s", "um/s": "µm/s", "μm/s": "µm/s",
    "ips": "in/s", "inch/s": "in/s", "fpm": "ft/min", "ipm": "in/min", "rad/sec": "rad/s",
    "m/sec": "m/s", "mm/sec": "mm/s", "deg/sec": "deg/s",
    # force and torque
    "newton": "N", "newtons": "N", "lb": "lbf", "lbs": "lbf", "kips": "kip", "oz": "ozf",
    "nm": "N·m",  # handled case-sensitively below: "Nm" is torque, "nm" a length
}

_COUNT_WORDS = {"counts", "count", "cts", "ct", "inc", "increments", "ticks", "pulses"}


def normalise_unit(unit: str) -> str:
    """Return the canonical spelling of a unit string (``"Nm"`` -> ``"N·m"``).

    Parameters
    ----------
    unit : str
        A unit as written in a file or on the command line, e.g. ``"N*m"``, ``"1/min"``,
        ``"um"``, ``"°"``, ``"lbf-in"``.

    Returns
    -------
    str
        The spelling used in :data:`UNIT_CONVERSIONS` when the unit is known, otherwise the
        stripped input (``"counts"`` and ``"counts/s"`` for encoder counts).

    Examples
    --------
    >>> normalise_unit("Nm"), normalise_unit("1/min"), normalise_unit("oz-in")
    ('N·m', 'rpm', 'oz·in')
    """
    text = unit.strip().replace("μ", "µ").replace("⋅", "·")
    if not text:
        return text
    if text in ("Nm", "NM"):
        return "N·m"
    if text == "nm":
        return "nm"  # nanometre; torque in lower case is too ambiguous to guess
    # products: N*m, N.m, N m, N-m, lbf-in, oz in -> the middle dot
    prod = re.fullmatch(r"(mN|kN|N|lbf|lb|oz|ozf)\s*[*.·\- ]\s*(m|mm|cm|in|ft)", text)
    if prod:
        force = {"lb": "lbf", "ozf": "oz"}.get(prod.group(1), prod.group(1))
        return f"{force}·{prod.group(2)}"
    glued = re.fullmatch(r"(mN|kN|N)(mm|cm|m)", text)
    if glued:
        return f"{glued.group(1)}·{glued.group(2)}"
    low = text.lower()
    if low in _COUNT_WORDS or low in ("count(s)", "encoder counts"):
        return "counts"
    head, sep, tail = low.partition("/")
    if sep and head in _COUNT_WORDS and tail in ("s", "sec"):
        return "counts/s"
    for table in UNIT_CONVERSIONS.values():
        if text in table:
            return text
    if low in _SPELLINGS:
        return _SPELLINGS[low]
    electrical = {"v": "V", "volt": "V", "volts": "V", "mv": "mV", "a": "A", "amp": "A",
                  "amps": "A", "ampere": "A", "amperes": "A", "ma": "mA"}
    return electrical.get(low, text)


def known_units(column: str) -> list[str]:
    """Return the unit spellings :func:`to_si` accepts for a record column.

    Parameters
    ----------
    column : {"t", "x", "v", "u"}
        Record column.

    Returns
    -------
    list of str
        Canonical units, including ``counts`` (``counts/s`` for velocity) where an encoder
        resolution can convert them.
    """
    units = list(UNIT_CONVERSIONS[column])
    if column == "x":
        units.append("counts")
    elif column == "v":
        units.append("counts/s")
    return units


def to_si(column: str, unit: str, *, source: str = "", counts_per_rev: float | None = None,
          counts_per_metre: float | None = None) -> tuple[str, float]:
    """Return the SI unit and the factor that converts a column's values to it.

    Parameters
    ----------
    column : {"t", "x", "v", "u"}
        Record column: time, position, velocity, force or torque.
    unit : str
        Unit as found in the file or given with ``--unit`` (any spelling of
        :func:`normalise_unit`).
    source : str
        File name for the error message.
    counts_per_rev : float, optional
        Encoder counts per revolution [1/rev]; converts ``counts`` to rad.
    counts_per_metre : float, optional
        Encoder counts per metre [1/m]; converts ``counts`` to m.

    Returns
    -------
    tuple of (str, float)
        SI unit and factor [SI unit per file unit].

    Raises
    ------
    FileFormatError
        If the unit is unknown (the message lists the known ones), electrical (needs a
        scale), or in counts without an encoder resolution.

    Examples
    --------
    >>> to_si("v", "rpm")[0], round(to_si("u", "kip")[1], 3)
    ('rad/s', 4448.222)
    """
    where = f"{source}: " if source else ""
    canonical = normalise_unit(unit)
    table = UNIT_CONVERSIONS[column]
    if canonical in table:
        return table[canonical]
    if canonical in ("counts", "counts/s") and column in ("x", "v"):
        if (counts_per_rev is None) == (counts_per_metre is None):
            raise FileFormatError(
                f"{where}column {column!r} is in encoder counts; give exactly one of "
                "--counts-per-rev N or --counts-per-metre N (Python: counts_per_rev=, "
                f"counts_per_metre=) so it can be converted to rad or m; got {unit!r}")
        for value, name in ((counts_per_rev, "--counts-per-rev"),
                            (counts_per_metre, "--counts-per-metre")):
            if value is not None and not (math.isfinite(value) and value > 0):
                raise FileFormatError(f"{name} must be a positive count; got {value}")
        base = ("rad", 2 * math.pi / counts_per_rev) if counts_per_rev else (
            "m", 1.0 / counts_per_metre)
        return (base[0] + ("/s" if column == "v" else ""), base[1])
    if canonical == "%":
        raise FileFormatError(
            f"{where}column {column!r} is in %, a fraction of a rated or nominal value that "
            f"the file does not give; state it with --scale {column}=RATED/100 (e.g. "
            f"--scale {column}=0.5/100 for 0.5 N·m rated; the scaled values are then SI)")
    if canonical in ELECTRICAL_UNITS:
        raise FileFormatError(
            f"{where}column {column!r} is in {unit!r}, an electrical unit; driveid does not "
            f"guess the gain: give it with --scale {column}=FACTOR (e.g. --scale u=200 for "
            "200 N per V; the scaled values are then taken as SI, or as the unit given with "
            f"--unit {column}=UNIT)")
    wrong = wrong_role(column, canonical)
    if wrong:
        raise FileFormatError(f"{where}{wrong}")
    raise FileFormatError(
        f"{where}column {column!r} is in {unit!r}, which driveid does not know; known units "
        f"for {column!r}: {', '.join(known_units(column))}; state the right unit with --unit "
        f"{column}=UNIT or convert the column with --scale {column}=FACTOR; got {unit!r}")


_BRACKET = re.compile(r"^(?P<name>.*?\S)\s*\[(?P<unit>[^\]]*)\]\s*$")
_PAREN = re.compile(r"^(?P<name>.*?\S)\s*\((?P<unit>[^)]*)\)\s*$")
_SLASH = re.compile(r"^(?P<name>.*?\S)\s+/\s*(?P<unit>\S.*?)\s*$")
_IN = re.compile(r"^(?P<name>.*?\S)\s+in\s+(?P<unit>\S+)\s*$")
_GLUED_SLASH = re.compile(r"^(?P<name>[^/\s]+)/(?P<unit>[^/\s]+(?:/[^/\s]+)?)$")
_COMMA = re.compile(r"^(?P<name>.*?\S)\s*,\s*(?P<unit>\S+)$")


_ROLES = {"t": ("time", "--time", "--time COL"),
          "x": ("position", "--position", "--channel x1=COL"),
          "v": ("velocity", "--velocity", "--channel v1=COL"),
          "u": ("force or torque", "--force", "--input COL")}


def wrong_role(column: str, unit: str) -> str | None:
    """Say that a column picked for one role is in a unit of another, or return None.

    ``--position t`` read a time column as the position: "column 'x' is in 's', which
    driveid does not know" named an internal column and called seconds unknown (fifth
    hostile campaign).

    Parameters
    ----------
    column : {"t", "x", "v", "u"}
        The role the column was read for.
    unit : str
        Its unit, normalised (:func:`normalise_unit`).

    Returns
    -------
    str or None
        The message, or None when ``unit`` belongs to no other role either.
    """
    for other, table in UNIT_CONVERSIONS.items():
        if other != column and unit in table and other in _ROLES and column in _ROLES:
            role, option, drive = _ROLES[column]
            return (f"the column read as the {role} is in {unit}, a unit of {_ROLES[other][0]}"
                    f": it is likely the wrong column; choose the {role} column with "
                    f"{option} COL (identify drive: {drive}; driveid inspect FILE lists the "
                    "columns)")
    return None


def split_header(text: str) -> tuple[str, str | None]:
    """Split a column header into its name and unit (``None`` when it states none).

    Parameters
    ----------
    text : str
        A header field: ``x [deg]``, ``x (deg)``, ``x / deg``, ``x in deg``,
        ``Weg &b_A1 / rad``, ``Zeit t / s`` or a bare name.

    Returns
    -------
    tuple of (str, str or None)
        The name (stripped) and the unit in canonical spelling.

    Examples
    --------
    >>> split_header("Weg &b_A1 / rad")
    ('Weg &b_A1', 'rad')
    >>> split_header("v / m/s"), split_header("x in deg"), split_header("speed(rpm)")
    (('v', 'm/s'), ('x', 'deg'), ('speed', 'rpm'))
    >>> split_header("Position, mm"), split_header("theta_m")
    (('Position', 'mm'), ('theta_m', None))
    >>> split_header("pos (3)"), split_header("q[2]")
    (('pos (3)', None), ('q[2]', None))
    """
    field = text.strip().strip('"').strip("'").strip()
    for pattern in (_BRACKET, _PAREN, _SLASH, _IN):
        match = pattern.match(field)
        if match and match.group("unit").strip():
            if pattern in (_BRACKET, _PAREN) and not _could_be_unit(match.group("unit")):
                return field, None  # 'pos (3)', 'q[2]', 'Force (channel 1)': part of the name
            return match.group("name").strip(), normalise_unit(match.group("unit"))
    # only with a unit driveid knows; never "name_unit": theta_m, tau_m are subscripts
    for pattern in (_GLUED_SLASH, _COMMA):
        match = pattern.match(field)
        if match and _is_known(normalise_unit(match.group("unit"))):
            return match.group("name"), normalise_unit(match.group("unit"))
    return field, None


_LABEL_WORDS = {"measured", "meas", "actual", "act", "target", "command", "commanded", "cmd",
                "desired", "setpoint", "reference", "ref", "motor", "load", "encoder", "raw",
                "filtered", "left", "right", "master", "slave", "model", "predicted",
                "estimated", "feedback", "demand", "abs", "rel", "absolute", "relative"}


def _could_be_unit(text: str) -> bool:
    """Tell a unit in brackets from an index or label that belongs to the name.

    Known units always are; a bare number (``pos (3)``, a servo or joint number), text with
    spaces (``Force (channel 1)``) or without a letter never is. Other single words
    (``x [furlong]``) are taken as units so that an unknown unit is reported, not dropped.
    """
    text = text.strip()
    if _is_known(normalise_unit(text)):
        return True
    if text.lower() in _LABEL_WORDS:
        return False  # 'Position (measured)', 'Torque (motor)'
    if re.fullmatch(r"[+-]?\d+", text) or not re.search(r"[^\W\d_]|[°%\"']", text):
        return False
    return not re.search(r"\s", text) and len(text) <= 12


def known_unit(unit: str) -> bool:
    """Return whether a unit string (any spelling) is one driveid knows.

    Parameters
    ----------
    unit : str
        E.g. ``"mm"``, ``"1/min"``, ``"V"``.

    Returns
    -------
    bool
        True for units of :data:`UNIT_CONVERSIONS`, counts and electrical units.
    """
    return _is_known(normalise_unit(unit))


def _is_known(unit: str) -> bool:
    return unit in ELECTRICAL_UNITS or unit in ("counts", "counts/s") or any(
        unit in table for table in UNIT_CONVERSIONS.values())
