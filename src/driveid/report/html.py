"""The HTML report: one self-contained file a colleague can open (issue 15).

One file, no network: figures are inline PNG (base64 ``data:`` URIs), the style sheet is
inline, and there is no JavaScript. The page shows, for each estimate, what was measured
(inputs with SHA-256, window, units, rows), the parameters with 95 % intervals
(value ± 1.96 standard errors, the normal approximation the estimators' standard errors are
built for), the method's figures, the validation overlay and fit where given, the warnings,
and how to reproduce it (command line, driveid version, date). Several estimates are also
compared side by side in one table.

The page is rendered from the Jinja2 template ``templates/report.html.j2`` (package data)
with autoescaping on, so file names and warnings cannot inject markup.
"""

from __future__ import annotations

import base64
import datetime as _dt
import io
import math
import platform
import shlex
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["Z95", "render_report", "write_report", "load_results"]

#: Two-sided 95 % quantile of the standard normal distribution [-].
Z95 = 1.959963984540054


@dataclass
class _Entry:
    """One estimate as the template shows it."""

    label: str
    estimate: Any
    command: str | None
    version: str
    figures: list[dict[str, str]] = field(default_factory=list)
    comparisons: list[dict[str, Any]] = field(default_factory=list)


def render_report(estimates: Any, *, figures: Sequence[Any] = (),
                  comparisons: Sequence[Any] = (), command: Sequence[str] | str | None = None,
                  title: str | None = None, generated: _dt.datetime | None = None) -> str:
    """Return the HTML text of a self-contained report of one or more estimates.

    Parameters
    ----------
    estimates : Estimate, mapping, or sequence of them
        The results; a mapping is a ``driveid-result/1`` dict (``--json`` output), converted
        with :meth:`driveid.identify.core.estimate.Estimate.from_dict`, whose ``command`` and
        ``driveid`` version are shown under "How to reproduce".
    figures : sequence
        Figures of the method, shown with the first estimate: matplotlib figures (embedded
        as PNG), PNG or SVG file paths, PNG bytes, or ``(caption, figure)`` pairs.
    comparisons : sequence
        Validation results (duck-typed, e.g. from :func:`driveid.validate.compare`): each
        has ``.plot()`` returning a figure (overlay and residuals) and ``.fit`` (fit [%],
        a number or a mapping of channel -> number). Shown with the first estimate.
    command : sequence of str or str, optional
        The command line that made the estimates (``sys.argv``); overrides the one stored
        in a result dict.
    title : str, optional
        Page title; default "driveid report: <method>".
    generated : datetime, optional
        Time stamp shown on the page [UTC]; default now.

    Returns
    -------
    str
        The HTML document (UTF-8 text, no external references).

    Raises
    ------
    ValueError
        If ``estimates`` is empty or a dict is not of schema ``driveid-result/1``.

    Examples
    --------
    >>> from driveid.identify.core.estimate import Estimate, Parameter
    >>> est = Estimate("logdec-lsq", {"K": Parameter(16.0, 0.01, "N·m/rad"),
    ...                               "J": Parameter(1.0, unit="kg·m²", fixed=True)})
    >>> html = render_report(est)
    >>> "fixed (given)" in html and "<script" not in html
    True
    """
    from driveid import __version__

    entries = [_entry(item, i) for i, item in enumerate(_as_list(estimates))]
    if not entries:
        raise ValueError("render_report needs at least one estimate; got none")
    if command is not None:
        text = command if isinstance(command, str) else _shell(command)
        for entry in entries:
            entry.command = text
    entries[0].figures = [_figure(f, i) for i, f in enumerate(figures, 1)]
    entries[0].comparisons = [_comparison(c, i) for i, c in enumerate(comparisons, 1)]
    for entry in entries:
        entry.estimate = _view(entry.estimate)
    methods = sorted({e.estimate["method"] for e in entries})
    generated = generated or _dt.datetime.now(_dt.UTC)
    return _template().render(
        title=title or f"driveid report: {', '.join(methods)}",
        entries=entries,
        comparison=_side_by_side(entries) if len(entries) > 1 else None,
        version=__version__,
        python=platform.python_version(),
        generated=generated.astimezone(_dt.UTC).strftime("%Y-%m-%d %H:%M:%S UTC"),
        z95=Z95,
    )


def write_report(estimates: Any, path: str | Path, *, figures: Sequence[Any] = (),
                 comparisons: Sequence[Any] = (), command: Sequence[str] | str | None = None,
                 title: str | None = None, overwrite: bool = False) -> Path:
    """Write a self-contained HTML report of one or more estimates (atomically).

    Parameters
    ----------
    estimates : Estimate, mapping, or sequence of them
        The results (see :func:`render_report`).
    path : str or Path
        The ``.html`` file to write.
    figures : sequence
        Figures of the method (see :func:`render_report`).
    comparisons : sequence
        Validation results with ``.plot()`` and ``.fit`` (see :func:`render_report`).
    command : sequence of str or str, optional
        The command line that made the estimates.
    title : str, optional
        Page title.
    overwrite : bool
        Replace an existing file (CLI ``--overwrite``).

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    OverwriteError
        If ``path`` exists and ``overwrite`` is False.
    """
    from driveid.io.safe_write import atomic_write_text, check_destination

    check_destination(path, overwrite=overwrite)  # refuse before rendering figures
    html = render_report(estimates, figures=figures, comparisons=comparisons,
                         command=command, title=title)
    return atomic_write_text(path, html, overwrite=overwrite)


def load_results(paths: Sequence[str | Path]) -> list[Any]:
    """Read result files written by ``--json`` (schema ``driveid-result/1``).

    Parameters
    ----------
    paths : sequence of str or Path
        JSON files.

    Returns
    -------
    list of dict
        The parsed results, in order (each checked by :meth:`Estimate.from_dict`).

    Raises
    ------
    FileFormatError
        If a file is not JSON or not a driveid result.
    """
    from driveid.errors import FileFormatError
    from driveid.identify.core.estimate import Estimate
    from driveid.io.consistency import load_json

    results = []
    for path in paths:
        try:  # nesting thousands deep was a RecursionError (exit 70)
            data = load_json(Path(path).read_bytes(), str(path), constants=True)
        except FileFormatError as exc:
            raise FileFormatError(f"{exc}; give a file written by an identify command's "
                                  "--json") from None
        try:
            if not isinstance(data, Mapping):
                raise ValueError(f"got a JSON {type(data).__name__}, not an object")
            Estimate.from_dict(data)
        except (ValueError, KeyError, TypeError, AttributeError) as exc:
            raise FileFormatError(
                f"{path} is not a driveid result ({exc}); give a file written by an "
                "identify command's --json") from None
        results.append(data)
    return results


def _as_list(estimates: Any) -> list[Any]:
    if isinstance(estimates, Mapping) or hasattr(estimates, "params"):
        return [estimates]
    return list(estimates)


def _entry(item: Any, index: int) -> _Entry:
    from driveid import __version__
    from driveid.identify.core.estimate import Estimate

    command, version = None, __version__
    if isinstance(item, Mapping):
        if item.get("command"):
            command = _shell(item["command"])
        version = str(item.get("driveid") or version)
        item = Estimate.from_dict(item)
    names = [Path(str(i.get("path"))).name for i in item.inputs if i.get("path")]
    label = f"{index + 1}. {item.method}" + (f" — {', '.join(names)}" if names else "")
    return _Entry(label=label, estimate=item, command=command, version=version)


def _shell(argv: Sequence[Any]) -> str:
    words = [str(a) for a in argv]
    if words and Path(words[0]).name == "driveid":
        words[0] = "driveid"  # the installed script, not its path in one venv
    return shlex.join(words)


def _view(est: Any) -> dict[str, Any]:
    """Plain values the template shows for one estimate (all text pre-formatted)."""
    params = []
    for name, par in est.params.items():
        params.append({"name": name, "unit": par.unit, **_interval(par)})
    return {
        "method": est.method,
        "params": params,
        "inputs": [_input_view(i) for i in est.inputs],
        "warnings": list(est.warnings),
        "diagnostics": [(k, _diagnostic(k, v)) for k, v in est.diagnostics.items()],
        "correlation": _correlation(est.covariance),
    }


def _interval(par: Any) -> dict[str, str]:
    value = _num(par.value, 6)
    if par.fixed:
        return {"value": value, "pm": "fixed (given)", "interval": "fixed (given)",
                "kind": "fixed"}
    se = float(par.stderr)
    if not math.isfinite(se):
        return {"value": value, "pm": "not available", "interval": "not available",
                "kind": "na"}
    half = Z95 * se
    low, high = par.value - half, par.value + half
    digits = 6
    if half > 0 and max(abs(low), abs(high)) > 0:
        # bounds to the second significant digit of the half-width (16 ± 0.00016 gives
        # 15.99994 … 16.00026, not 16 … 16.0003)
        digits = math.floor(math.log10(max(abs(low), abs(high)))) - math.floor(
            math.log10(half)) + 2
        digits = min(max(digits, 2), 15)
    return {"value": value, "pm": f"± {_num(half, 2)}",
            "interval": f"[{_num(low, digits)}, {_num(high, digits)}]", "kind": "estimated"}


def _input_view(item: Mapping[str, Any]) -> dict[str, str]:
    window = item.get("window")
    units = item.get("units") or {}
    columns = item.get("columns") or {}
    in_file = item.get("units_in_file") or {}
    cols = ", ".join(
        f"{k} ← {v!s} [{units.get(k, '?')}"
        + (f", file: {in_file[v]}" if v in in_file and in_file[v] != units.get(k) else "")
        + "]"
        for k, v in columns.items())
    reading = item.get("reading") or {}
    if reading:  # how the file was read, as the options that read it again (issue 26)
        from driveid.io.reading_options import reading_as_cli

        cols = (cols + "; " if cols else "") + "read with " + reading_as_cli(reading)
    return {
        "path": str(item.get("path") or "(in memory)"),
        "sha256": str(item.get("sha256") or "—"),
        "rows": "—" if item.get("rows") is None else str(item["rows"]),
        "window": (f"{_num(window[0], 6)} … {_num(window[1], 6)} s"
                   if window and len(window) == 2 else "—"),
        "columns": cols or ", ".join(f"{k} [{u}]" for k, u in units.items()) or "—",
    }


def _correlation(covariance: Mapping[str, Any] | None) -> dict[str, Any] | None:
    if not covariance:
        return None
    import numpy as np

    matrix = np.asarray(covariance["matrix"], dtype=float)
    names = list(covariance["names"])
    if matrix.ndim != 2 or matrix.shape != (len(names), len(names)) or len(names) < 2:
        return None
    sd = np.sqrt(np.clip(np.diag(matrix), 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        corr = matrix / np.outer(sd, sd)
    rows = [(n, [_num(c, 2) if math.isfinite(c) else "—" for c in row])
            for n, row in zip(names, corr, strict=True)]
    return {"names": names, "rows": rows}


def _side_by_side(entries: Sequence[_Entry]) -> dict[str, Any]:
    names: list[str] = []
    for entry in entries:
        names += [p["name"] for p in entry.estimate["params"] if p["name"] not in names]
    rows = []
    for name in names:
        cells, unit = [], ""
        for entry in entries:
            par = next((p for p in entry.estimate["params"] if p["name"] == name), None)
            if par is None:
                cells.append({"value": "—", "pm": "", "kind": "absent"})
            else:
                unit = unit or par["unit"]
                cells.append(par)
        rows.append({"name": name, "unit": unit, "cells": cells})
    return {"labels": [e.label for e in entries], "rows": rows}


def _figure(item: Any, index: int) -> dict[str, str]:
    caption = f"Figure {index}"
    if isinstance(item, tuple) and len(item) == 2:
        caption, item = str(item[0]), item[1]
    if isinstance(item, (bytes, bytearray)):
        return {"caption": caption, "src": _data_uri(bytes(item), "image/png")}
    if isinstance(item, (str, Path)):
        path = Path(item)
        mime = "image/svg+xml" if path.suffix.lower() == ".svg" else "image/png"
        return {"caption": caption, "src": _data_uri(path.read_bytes(), mime)}
    if not hasattr(item, "savefig"):
        raise TypeError(f"figure {index} must be a matplotlib figure, PNG/SVG path or PNG "
                        f"bytes; got {type(item).__name__}")
    return {"caption": caption, "src": _data_uri(_png(item), "image/png")}


def _png(fig: Any) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    try:
        from driveid.report._pyplot import pyplot

        pyplot().close(fig)
    except ImportError:  # pragma: no cover - matplotlib is a dependency
        pass
    return buffer.getvalue()


def _comparison(item: Any, index: int) -> dict[str, Any]:
    fit = getattr(item, "fit", None)
    if isinstance(fit, Mapping):
        fit_text = ", ".join(f"{k}: {_num(v, 4)} %" for k, v in fit.items())
    elif fit is None:
        fit_text = "—"
    else:
        fit_text = f"{_num(fit, 4)} %"
    figure = _figure(("Validation: measured and simulated, residuals", item.plot()), index)
    return {"fit": fit_text, "figure": figure}


def _data_uri(data: bytes, mime: str) -> str:
    return f"data:{mime};base64,{base64.b64encode(data).decode('ascii')}"


def _num(value: Any, digits: int) -> str:
    try:
        value = float(value)
    except (TypeError, ValueError):
        return str(value)
    if not math.isfinite(value):
        return "—"
    return f"{value:.{digits}g}"


def _diagnostic(key: str, value: Any) -> str:
    """One diagnostic as text; the noise model and adequacy of a fit in plain words."""
    if key == "noise_model" and isinstance(value, dict):
        coeffs = ", ".join(_num(a, 3) for a in value.get("ar", [])[:6])
        more = " …" if len(value.get("ar", [])) > 6 else ""
        return (f"{value.get('kind')} ({coeffs}{more}); innovation sd "
                f"{_num(value.get('innovation_std') or float('nan'), 3)}, "
                f"n_eff {_num(value.get('n_eff', float('nan')), 4)} of {value.get('n')}"
                + (" (anti-persistent)" if isinstance(value.get("n"), int)
                   and value.get("n_eff", 0) > value["n"] else ""))
    if key == "adequacy" and isinstance(value, dict):
        white = value.get("whiteness") or {}
        words = "adequate" if value.get("adequate") else "NOT adequate"
        return (f"{words}: Ljung-Box p = {_num(white.get('p_value', float('nan')), 3)}; "
                f"error bars {value.get('covariance')}; "
                + " ".join(value.get("notes", []))[:300])
    return _short(value)


def _short(value: Any) -> str:
    if isinstance(value, bool) or value is None:
        return str(value)
    if isinstance(value, (int, float)):
        return _num(value, 6)
    text = str(value)
    return text if len(text) <= 120 else text[:117] + "…"


def _template() -> Any:
    import jinja2

    env = jinja2.Environment(
        loader=jinja2.PackageLoader("driveid.report", "templates"),
        autoescape=True, undefined=jinja2.StrictUndefined, trim_blocks=True,
        lstrip_blocks=True)
    return env.get_template("report.html.j2")
