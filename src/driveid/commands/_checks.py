"""Click types and checks for numeric options (issue 12): no NaN, inf or absurd value passes.

``--noise nan`` and ``--K nan`` were once taken as "none", ``--mass 1e308`` printed K = inf
with exit 0 and ``--omega-c 1e9`` tried to allocate 32 TiB. Use these types on every numeric
option::

    @click.option("--noise", type=NonNegativeFloat(), default=0.0)
    @click.option("--fs", type=PositiveFloat(max=1e7))
    @click.option("--n-D", type=BoundedInt(1000, min=1))

and :func:`check_allocation` once the sizes are known. A bad value is a click usage error
(exit 2, one line naming the option, the rule and the value).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import click

from driveid.io.consistency import available_memory, check_allocation, check_count

__all__ = ["FiniteFloat", "PositiveFloat", "NonNegativeFloat", "BoundedInt",
           "check_allocation", "check_count", "available_memory", "FLOAT_LIMIT",
           "parse_quantisation", "bootstrap_options", "SEED"]

#: Largest magnitude a float option accepts by default: far beyond any physical value in
#: SI units, yet small enough that squares and products of two options stay finite.
FLOAT_LIMIT = 1e100

#: Most bootstrap replicates a command takes (``--bootstrap``) [-].
MAX_BOOTSTRAP = 10_000


class FilePath(click.Path):
    """A file path option: a trailing ``/`` is refused.

    ``Path("f.png/")`` drops the slash, so ``--figure f.png/`` (a folder, by its spelling)
    wrote the file ``f.png`` (fifth hostile campaign, 2026-11-28).
    """

    def __init__(self) -> None:
        super().__init__(dir_okay=False, path_type=Path)

    def convert(self, value: Any, param: click.Parameter | None,
                ctx: click.Context | None) -> Any:
        if isinstance(value, str) and value.endswith(("/", os.sep)):
            self.fail(f"{value!r} ends in '/', so it names a folder; give a file name "
                      "without the trailing slash", param, ctx)
        return super().convert(value, param, ctx)


class FiniteFloat(click.ParamType):
    """A finite float, optionally bounded: NaN, inf and magnitudes above ``max`` refused.

    Parameters
    ----------
    min : float, optional
        Smallest value accepted (inclusive) [option's unit].
    max : float
        Largest magnitude accepted [option's unit]; default :data:`FLOAT_LIMIT`.
    allow_inf : bool
        Accept ``inf`` (e.g. "no limit" for ``--abort-limit``); NaN is always refused.
    """

    name = "float"
    rule = "a finite number"

    def __init__(self, min: float | None = None, max: float = FLOAT_LIMIT,
                 allow_inf: bool = False) -> None:
        self.min = min
        self.max = max
        self.allow_inf = allow_inf

    def _check(self, value: float) -> str | None:
        return None

    def convert(self, value: Any, param: Any, ctx: Any) -> float:
        """Convert and check a value (click API).

        Parameters
        ----------
        value : str or float
            The text given on the command line (or a default).
        param : click.Parameter or None
            The option.
        ctx : click.Context or None
            The context.

        Returns
        -------
        float
            The checked value.
        """
        if isinstance(value, float) and math.isfinite(value):
            number = value
        else:
            try:
                number = float(value)
            except (TypeError, ValueError):
                self.fail(f"expected {self.rule}; got {value!r}", param, ctx)
        if self.allow_inf and number == math.inf:
            return number
        if not math.isfinite(number):
            self.fail(f"must be {self.rule}; got {value!r} (NaN and inf are not accepted; "
                      "leave the option out for 'none')", param, ctx)
        if abs(number) > self.max:
            self.fail(f"must be at most {self.max:g} in magnitude; got {value!r} (check the "
                      "unit: options are in SI)", param, ctx)
        if self.min is not None and number < self.min:
            self.fail(f"must be >= {self.min:g}; got {value!r}", param, ctx)
        problem = self._check(number)
        if problem:
            self.fail(f"must be {problem}; got {value!r}", param, ctx)
        return number


class PositiveFloat(FiniteFloat):
    """A finite float > 0 (rates, durations, masses, stiffnesses)."""

    name = "positive float"
    rule = "a finite number > 0"

    def _check(self, value: float) -> str | None:
        return None if value > 0 else "> 0"


class NonNegativeFloat(FiniteFloat):
    """A finite float >= 0 (noise levels, delays, friction magnitudes)."""

    name = "non-negative float"
    rule = "a finite number >= 0"

    def _check(self, value: float) -> str | None:
        return None if value >= 0 else ">= 0"


class BoundedInt(click.ParamType):
    """An integer between ``min`` and ``limit`` (counts of runs, gains, iterations).

    Parameters
    ----------
    limit : int
        Largest value accepted [-].
    min : int
        Smallest value accepted [-].
    override : str, optional
        How a user lifts the limit, appended to the message.
    """

    name = "integer"

    def __init__(self, limit: int, min: int = 0, override: str | None = None) -> None:
        self.limit = int(limit)
        self.min = int(min)
        self.override = override

    def convert(self, value: Any, param: Any, ctx: Any) -> int:
        """Convert and check a value (click API).

        Parameters
        ----------
        value : str or int
            The text given on the command line (or a default).
        param : click.Parameter or None
            The option.
        ctx : click.Context or None
            The context.

        Returns
        -------
        int
            The checked value.
        """
        if isinstance(value, bool):
            self.fail(f"expected an integer; got {value!r}", param, ctx)
        if isinstance(value, int):
            number = value
        else:
            try:
                number = int(str(value).strip())
            except ValueError:
                self.fail(f"expected an integer; got {value!r}", param, ctx)
        if number < self.min:
            self.fail(f"must be >= {self.min}; got {number}", param, ctx)
        if number > self.limit:
            hint = f"; {self.override}" if self.override else ""
            self.fail(f"must be at most {self.limit}; got {number}{hint}", param, ctx)
        return number


#: Type of every ``--seed`` option: numpy's generators take a non-negative integer (issue 28:
#: ``--seed -1`` ended in an internal error on every command that has the option).
SEED = BoundedInt(2**64 - 1, min=0)


def parse_quantisation(text: str) -> float | str | None:
    """Parse ``--quantisation``: ``auto``, ``none`` or an encoder step [m or rad].

    Parameters
    ----------
    text : str
        The option's value.

    Returns
    -------
    float, "auto" or None
        The step [m or rad], ``"auto"`` (detect it) or None (not quantised).

    Raises
    ------
    click.BadParameter
        Anything else, or a step that is not positive and finite.
    """
    value = text.strip().lower()
    if value in ("auto", "none"):
        return None if value == "none" else "auto"
    try:
        step = float(value)
    except ValueError:
        raise click.BadParameter(f"give 'auto', 'none' or a step in m or rad; got {text!r}",
                                 param_hint="--quantisation") from None
    if not (0 < step < math.inf):
        raise click.BadParameter(f"the encoder step must be positive and finite; got {text!r}",
                                 param_hint="--quantisation")
    return step


def bootstrap_options(default_replicates: int) -> Any:
    """Add ``--quantisation``, ``--bootstrap`` and ``--seed`` (the encoder bootstrap, oe).

    Parameters
    ----------
    default_replicates : int
        Default of ``--bootstrap`` [-].

    Returns
    -------
    callable
        A decorator; the command receives ``quantisation`` (text, see
        :func:`parse_quantisation`), ``bootstrap`` and ``seed``.
    """
    def decorate(command: Any) -> Any:
        command = click.option("--seed", type=SEED, default=None,
                               help="Seed of the bootstrap (oe).")(command)
        # each replicate is one more whole-record fit: 1e8 once ran on silently (issue 28)
        limit = BoundedInt(MAX_BOOTSTRAP, min=1, override="each replicate is one more fit; "
                           "a few hundred give error bars good to a few per cent")
        command = click.option("--bootstrap", type=limit, default=default_replicates,
                               show_default=True,
                               help="Bootstrap repeats for quantised records (oe).")(command)
        return click.option("--quantisation", default="auto", show_default=True,
                            help="Encoder step [m or rad] for the bootstrap error bars (oe): "
                                 "'auto' detects it, 'none' treats the noise as white."
                            )(command)
    return decorate
