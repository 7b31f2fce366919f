"""How every identify command shows its result (defined once).

``@output_options`` adds ``--json``, ``--series``, ``--figure PATH``, ``--report PATH``,
``--overwrite``, ``--strict`` and ``--quiet`` and passes one :class:`OutputOptions` to the
callback as ``output_opts``. :func:`emit` prints the estimate (table or the result schema of
:meth:`driveid.identify.core.estimate.Estimate.to_dict`), writes the figure and report, and prints
the estimate's warnings on stderr (``--strict``: a warning is an error, exit 2).
"""

from __future__ import annotations

import functools
import json
import re
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import click

from driveid.commands._checks import FilePath

__all__ = ["OutputOptions", "output_options", "emit", "plot_of", "cli_text", "noise_words"]


@dataclass(frozen=True)
class OutputOptions:
    """What to show and write.

    Attributes
    ----------
    as_json : bool
        Print the result schema as JSON instead of a table.
    series : bool
        Include long time series in the JSON.
    figure : Path or None
        PNG (or PDF/SVG) figure to write.
    report : Path or None
        Self-contained HTML report to write.
    overwrite : bool
        Replace existing figure/report files.
    strict : bool
        Turn the estimate's warnings into an error (exit 2).
    quiet : bool
        No progress output.
    """

    as_json: bool = False
    series: bool = False
    figure: Path | None = None
    report: Path | None = None
    overwrite: bool = False
    strict: bool = False
    quiet: bool = False


def output_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """Add the shared output options to a click command; pass ``output_opts`` to it."""
    options = [
        click.option("--json", "out_json", is_flag=True,
                     help="Print the result as JSON (schema: docs, 'Result schema')."),
        click.option("--series", "out_series", is_flag=True,
                     help="Include long time series in the JSON."),
        click.option("--figure", "out_figure", default=None,
                     type=FilePath(),
                     help="Write a figure (PNG, PDF or SVG)."),
        click.option("--report", "out_report", default=None,
                     type=FilePath(),
                     help="Write a self-contained HTML report."),
        click.option("--overwrite", "out_overwrite", is_flag=True,
                     help="Replace existing figure/report files."),
        click.option("--strict", "out_strict", is_flag=True,
                     help="Treat warnings as errors (exit 2), for scripts."),
        click.option("--quiet", "out_quiet", is_flag=True, help="No progress output."),
    ]

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        report = kwargs.get("out_report")
        if report is not None and report.suffix.lower() not in (".html", ".htm"):
            # the report is HTML whatever the name (a .pdf of HTML before; issue 28)
            raise click.BadParameter(
                f"the report is one HTML file; name it .html (got {str(report)!r}); for a "
                "PNG, PDF or SVG picture use --figure", param_hint="'--report'")
        kwargs["output_opts"] = OutputOptions(
            as_json=kwargs.pop("out_json"), series=kwargs.pop("out_series"),
            figure=kwargs.pop("out_figure"), report=kwargs.pop("out_report"),
            overwrite=kwargs.pop("out_overwrite"), strict=kwargs.pop("out_strict"),
            quiet=kwargs.pop("out_quiet"))
        return func(*args, **kwargs)

    for option in reversed(options):
        wrapper = option(wrapper)
    return wrapper


def emit(est: Any, opts: OutputOptions, *, records: Sequence[Any] = (),
         figure: Callable[[], Any] | None = None, header: str | None = None) -> Any:
    """Show an estimate as the options ask.

    The estimate is first completed: plausibility guards
    (:func:`driveid.identify.core._plausibility.check_plausibility`), the warnings raised while
    reading its records, and their provenance (``inputs``) when it has none.

    Parameters
    ----------
    est : Estimate
        The result.
    opts : OutputOptions
        From :func:`output_options`.
    records : sequence of Record
        The records it was estimated from (provenance, figure, report).
    figure : callable, optional
        Returns a matplotlib figure of the estimate; called only if ``--figure`` or
        ``--report`` was given.
    header : str, optional
        A line printed above the table.

    Returns
    -------
    Estimate
        The completed estimate that was shown.

    Raises
    ------
    IdentificationError
        Under ``--strict`` when the estimate carries warnings (``clean_errors`` prints it
        as one ``error:`` line, exit 2).
    """
    from click import UsageError

    from driveid.commands import captured_warnings, mark_printed
    from driveid.errors import IdentificationError
    from driveid.identify.core._plausibility import check_plausibility

    est = check_plausibility(est)
    est = est.with_warnings(*captured_warnings())
    if records and not est.inputs:
        est = est.with_inputs(records)
    for message in est.warnings:
        click.echo(f"warning: {cli_text(message)}", err=True)
    mark_printed(est.warnings)
    if opts.strict and est.warnings:
        raise IdentificationError(
            f"{len(est.warnings)} warning(s) under --strict (first: {est.warnings[0]}); "
            "drop --strict to get the estimate anyway")
    if opts.figure is not None and figure is None:
        raise UsageError("--figure: this command draws no figure; drop --figure (--report "
                         "still writes the tables)")
    fig = None
    if figure is not None and (opts.figure is not None or opts.report is not None):
        fig = figure()
    if opts.figure is not None and fig is not None:
        from driveid.report.figures import save_figure

        save_figure(fig, opts.figure, overwrite=opts.overwrite)
    if opts.report is not None:
        from driveid.report import html

        html.write_report([est], opts.report, figures=[fig] if fig is not None else [],
                          command=list(sys.argv), overwrite=opts.overwrite)
    if opts.as_json:
        click.echo(json.dumps(est.to_dict(series=opts.series, command=list(sys.argv)),
                              indent=2))
        return est
    if header:
        click.echo(header)
    click.echo(est.table())
    for path in (opts.figure, opts.report):
        if path is not None:
            click.echo(f"wrote {path}")
    return est


def plot_of(est: Any, records: Any) -> Any:
    """Return the method's figure of ``est`` over ``records`` (a Record or a sequence).

    Parameters
    ----------
    est : Estimate
        The result.
    records : Record or sequence of Record
        The data it came from.

    Returns
    -------
    matplotlib.figure.Figure
        From :func:`driveid.report.figures.plot_estimate`.
    """
    from driveid.report.figures import plot_estimate

    return plot_estimate(est, record=records)


# -- messages on the command line speak CLI (issue 26) ------------------------------------
#: Python keywords of the reading API -> the CLI option, for messages raised below a command.
_READING_OPTIONS = {"max_jitter": "--max-jitter", "counts_per_rev": "--counts-per-rev",
                    "counts_per_metre": "--counts-per-metre", "overwrite": "--overwrite",
                    "sign_magnitude": "--sign-magnitude", "fs": "--fs"}
_REPR = re.compile(r"\bnp\.(?:float|int|uint|complex|bool)\w*\(\s*([^()]*?)\s*\)|"
                   r"\bnp\.str_\(\s*([^()]*?)\s*\)")
_ASSIGN = re.compile(r"(?<![\w.\-])([a-z][a-z0-9_]*)=(None|True|False|[^\s,;)]+)?")
_PYTHON_ASIDE = re.compile(r"\s*\((?:Python|API)\s*:[^()]*(?:\([^()]*\)[^()]*)*\)")
# a keyword as the subject of a rule ('cutoff_hz must be below fs/2'); other words with an
# underscore (parameter names such as fk_mean in a warning) stay as they are
_IDENTIFIER = re.compile(r"(?<![\w.\-])([a-z][a-z0-9]*_[a-z0-9_]*[a-z0-9])"
                         r"(?=\s+(?:must|should|needs|takes|cannot|is not|has to)\b)")


def noise_words(noise: dict[str, Any]) -> str:
    """Describe a fit's noise model for a header line: kind and effective samples.

    ``n_eff`` above the row count is an anti-persistent residual (its long-run variance is
    below its variance), said in words so that it does not read as a counting error.
    """
    n_eff, n = noise.get("n_eff", float("nan")), noise.get("n")
    extra = ", anti-persistent" if isinstance(n, int) and n_eff > n else ""
    return f"{noise.get('kind')} (n_eff {n_eff:.0f} of {n} rows{extra})"


def _options_of_command() -> dict[str, str]:
    """Python name -> long option of the running click command (and its record options)."""
    options = dict(_READING_OPTIONS)
    ctx = click.get_current_context(silent=True)
    while ctx is not None:
        for param in getattr(ctx.command, "params", ()):
            if not isinstance(param, click.Option):
                continue
            longs = [o for o in param.opts if o.startswith("--")]
            if not longs:
                continue
            for flag in longs:
                options.setdefault(flag[2:].replace("-", "_"), flag)
            if param.name:
                options.setdefault(param.name, longs[0])
        ctx = ctx.parent
    return options


def cli_text(message: str) -> str:
    """Return a message for the command line: CLI option spellings, no Python reprs.

    The API speaks Python (``pass max_jitter=None``, ``cutoff_hz must be ...``); on the
    command line the same message names the options (``--max-jitter none``,
    ``--cutoff-hz``). ``(Python: ...)`` asides are dropped and numpy reprs
    (``np.float64(0.035)``) become their numbers.

    Parameters
    ----------
    message : str
        An error or warning text.

    Returns
    -------
    str
        The text to print.

    Examples
    --------
    >>> cli_text("jitter 3 %; pass max_jitter=None (Python: max_jitter=)")
    'jitter 3 %; give --max-jitter none'
    >>> cli_text("got np.float64(0.035)")
    'got 0.035'
    >>> cli_text("crop them out (Record.crop)")
    'crop them out (--t-start/--t-end, or FILE@T0:T1)'
    """
    text = _PYTHON_ASIDE.sub("", str(message))
    text = _REPR.sub(lambda m: m.group(1) if m.group(1) is not None else m.group(2), text)
    options = _options_of_command()

    def assign(match: re.Match) -> str:
        name, value = match.group(1), match.group(2)
        flag = options.get(name)
        if flag is None:
            return match.group(0)
        if value in (None, "True"):
            return flag
        if value == "False":
            return f"no {flag}"
        return f"{flag} {'none' if value == 'None' else value}"

    text = _ASSIGN.sub(assign, text)
    text = _IDENTIFIER.sub(lambda m: options.get(m.group(1), m.group(1)), text)
    text = text.replace("pass --", "give --")
    for python, cli in _PHRASES:
        text = text.replace(python, cli)

    def aside(match: re.Match) -> str:  # '(CLI: --overwrite)' after '--overwrite': said
        inner = match.group(1).strip()
        flag = re.match(r"--[\w-]+", inner)
        before = text[:match.start()]
        return "" if flag and flag.group(0) in before else match.group(0)

    return _CLI_ASIDE.sub(aside, text)


# API names in hints that have a command-line spelling
_PHRASES = (("with Record.crop", "with --t-start/--t-end (or FILE@T0:T1)"),
            ("(Record.crop)", "(--t-start/--t-end, or FILE@T0:T1)"))
_CLI_ASIDE = re.compile(r"\s*\(CLI:?\s*([^()]*)\)")
