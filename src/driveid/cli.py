"""The ``driveid`` command line: a thin layer over the public API.

Every subcommand calls one public function. One error boundary (issue 12) surrounds the
whole click invocation (:class:`_BoundaryGroup`), so every way a command can fail ends in
one line on stderr and a documented exit status:

==========================================================  ======  ===========================
what happened                                               status  stderr
==========================================================  ======  ===========================
success                                                     0       ``warning: ...`` lines only
bad input, usage error, refused overwrite, missing file     2       ``error: <rule, value, fix>``
unexpected exception (a bug)                                70      ``error: internal error ...``
Ctrl-C (also while starting, or inside a compiled kernel)   130     ``error: interrupted ...``
==========================================================  ======  ===========================

``driveid --debug ...`` adds the Python traceback. Python warnings raised while a command
runs (driveid's own, numpy/scipy ``RuntimeWarning``) are collected for that command only
(``warnings.catch_warnings``, not a process-wide filter) and printed once each as
``warning: ...``; library deprecation notices are dropped.
"""

from __future__ import annotations

import signal
import sys


def _interrupted_while_starting(signum, frame):  # pragma: no cover - needs a real Ctrl-C
    sys.stderr.write("error: interrupted (Ctrl-C) while starting; nothing was done\n")
    raise SystemExit(130)


# Ctrl-C while the command modules (scipy, numba, matplotlib) are imported: one line, 130.
_SIGINT_BEFORE = None
try:
    _SIGINT_BEFORE = signal.signal(signal.SIGINT, _interrupted_while_starting)
except ValueError:  # not the main thread (e.g. imported by a test runner's worker)
    pass

import traceback  # noqa: E402
import warnings  # noqa: E402
from typing import Any  # noqa: E402

import click  # noqa: E402

from driveid import __version__  # noqa: E402
from driveid.commands._lazy import LazyGroup  # noqa: E402
from driveid.errors import DriveIdError  # noqa: E402

if _SIGINT_BEFORE is not None:
    # a start-up handler installed earlier (e.g. by the package, same name) ends here too
    restore = (signal.default_int_handler
               if getattr(_SIGINT_BEFORE, "__name__", "") == "_interrupted_while_starting"
               else _SIGINT_BEFORE)
    signal.signal(signal.SIGINT, restore)

__all__ = ["main", "cli", "EXIT_USAGE", "EXIT_INTERNAL", "EXIT_INTERRUPTED"]

#: Exit status of an error the user can fix (bad input, usage, refused overwrite).
EXIT_USAGE = 2
#: Exit status of an unexpected exception (``EX_SOFTWARE`` of sysexits.h): a bug.
EXIT_INTERNAL = 70
#: Exit status after Ctrl-C (128 + SIGINT).
EXIT_INTERRUPTED = 130

_MAX_MESSAGE = 300
# Warnings that say nothing about the user's result (library housekeeping).
_DROPPED = (DeprecationWarning, PendingDeprecationWarning, FutureWarning, ImportWarning,
            ResourceWarning)


def _one_line(text: Any) -> str:
    from driveid.commands._output import cli_text  # CLI spellings, no reprs (issue 26)

    text = " ".join(cli_text(str(text)).split())
    return text if len(text) <= _MAX_MESSAGE else text[:_MAX_MESSAGE - 3] + "..."


def _warning_line(w: warnings.WarningMessage) -> str | None:
    category = w.category
    if issubclass(category, _DROPPED):
        return None
    message = _one_line(w.message)
    if issubclass(category, RuntimeWarning) and not issubclass(category, UserWarning):
        # numpy/scipy floating-point trouble: say what it means, not where it came from
        return (f"warning: numerical trouble during the computation ({message}); the result "
                "may be inaccurate - check the record for constant, tiny or non-finite stretches")
    return f"warning: {message}"


def _error_line(exc: BaseException) -> tuple[str, int]:
    """Return the one line and exit status of an exception that escaped a command."""
    if isinstance(exc, click.exceptions.NoArgsIsHelpError):
        return "", 2
    if isinstance(exc, click.UsageError):
        hint = ""
        if exc.ctx is not None:
            hint = f" (see '{exc.ctx.command_path} --help')"
        return f"error: {_one_line(exc.format_message())}{hint}", EXIT_USAGE
    if isinstance(exc, click.ClickException):
        return f"error: {_one_line(exc.format_message())}", EXIT_USAGE
    if isinstance(exc, DriveIdError):
        return f"error: {_one_line(exc)}", EXIT_USAGE
    if isinstance(exc, UnicodeDecodeError):
        return (f"error: a file is not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at offset "
                f"{exc.start}); save it as UTF-8 (plain CSV)", EXIT_USAGE)
    if isinstance(exc, OSError) and exc.errno is not None:
        # missing file, permission, folder given as file, disk full: the user can act
        where = f": {exc.filename}" if exc.filename else ""
        return f"error: {_one_line(exc.strerror or exc)}{where}", EXIT_USAGE
    if isinstance(exc, _damaged_file_errors()):
        # raised by numpy/scipy/json on a damaged file, before any driveid check could
        return (f"error: a file could not be read: it is damaged, empty or not in the format "
                f"its suffix says ({type(exc).__name__}: {_one_line(exc)[:120]}); check the "
                "files named on the command line", EXIT_USAGE)
    if isinstance(exc, MemoryError):
        return ("error: out of memory; the request is too large for this machine - use a "
                "shorter record (--t-start/--t-end), a lower rate or a smaller grid",
                EXIT_USAGE)
    return (f"error: internal error ({type(exc).__name__}: {_one_line(exc)}); this is a bug - "
            "please report it with the command line; rerun with --debug for the traceback",
            EXIT_INTERNAL)


# Numeric option policy, applied to every registered command by its option's name (so that
# commands registered later are covered too): NaN and inf are refused everywhere (--noise nan
# was once taken as "none"); these names must also be > 0, >= 0, or below a bound.
_POSITIVE = {"J", "mass", "duration", "fs", "opt_fs", "counts_per_rev", "counts_per_metre",
             "opt_counts_per_rev", "opt_counts_per_metre", "omega_c", "cutoff_hz", "rel_tol",
             "abort_limit"}
_NON_NEGATIVE = {"noise", "delay", "K", "stiffness"}
_POSITIVE_IN = {("run", "x0")}  # pho run: x0 is a magnitude
_INF_OK = {"abort_limit"}  # inf: no safety abort (run_pho_campaign's documented meaning)
#: Upper bounds of options whose large values only make sense as mistakes.
_UPPER = {"omega_c": 1e3, "delay": 10.0}
_INT_BOUNDS = {"modes": (1, 100), "decimate": (1, 10**6), "min_samples": (1, 10**9),
               "n_D": (1, 10**4), "min_peaks": (2, 10**4)}
#: Bytes per sample a simulating command holds (state, outputs, temporaries) [B].
_SIM_BYTES_PER_SAMPLE = 128


def _harden(command: click.Command) -> None:
    """Give every numeric option of ``command`` (and its subcommands) checked types."""
    from driveid.commands._checks import (
        BoundedInt,
        FiniteFloat,
        NonNegativeFloat,
        PositiveFloat,
    )

    if getattr(command, "_driveid_hardened", False):
        return
    command._driveid_hardened = True  # type: ignore[attr-defined]
    if isinstance(command, LazyGroup):
        command.on_load = _harden  # commands imported later get the same policy
    if isinstance(command, click.Group):
        for sub in command.commands.values():
            _harden(sub)
    names = set()
    for param in command.params:
        names.add(param.name)
        kind = param.type
        if isinstance(kind, FiniteFloat | BoundedInt):
            continue
        if isinstance(kind, click.types.FloatParamType):
            upper = _UPPER.get(param.name, 1e100)
            if param.name in _POSITIVE or (command.name, param.name) in _POSITIVE_IN:
                param.type = PositiveFloat(max=upper, allow_inf=param.name in _INF_OK)
            elif param.name in _NON_NEGATIVE:
                param.type = NonNegativeFloat(max=upper)
            else:
                param.type = FiniteFloat(max=upper)
        elif isinstance(kind, click.types.IntParamType) and param.name in _INT_BOUNDS:
            low, high = _INT_BOUNDS[param.name]
            param.type = BoundedInt(high, min=low)
    rate = "fs" if "fs" in names else None
    if "duration" in names and rate and command.callback is not None:
        command.callback = _sized(command.callback, command.name or "command")


def _sized(callback: Any, name: str) -> Any:
    """Wrap a simulating command: refuse a duration x rate that cannot fit in memory."""
    import functools

    @functools.wraps(callback)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        from driveid.commands._checks import check_allocation

        duration, fs = kwargs.get("duration"), kwargs.get("fs")
        if duration is not None and fs is not None:
            check_allocation(duration * fs + 1, _SIM_BYTES_PER_SAMPLE,
                             f"{name}: --duration {duration:g} s at {fs:g} Hz",
                             override="shorten --duration or lower the rate")
        return callback(*args, **kwargs)

    return wrapper


def _damaged_file_errors() -> tuple[type[BaseException], ...]:
    import json
    import zipfile

    kinds: list[type[BaseException]] = [EOFError, zipfile.BadZipFile, json.JSONDecodeError]
    try:
        from scipy.io.matlab import MatReadError

        kinds.append(MatReadError)
    except ImportError:  # pragma: no cover
        pass
    return tuple(kinds)


class _Interrupted(Exception):
    """Ctrl-C inside a command, carried past click (which would print a blank line)."""


def _show_notes(name: str) -> None:
    """Print a driveid logger's messages as notes on stderr.

    ``driveid.compile``: the one-time kernel compilation notice (on a terminal);
    ``driveid.cost``: the announcement of a long but feasible fit (always, issue 28).
    """
    import logging

    class _CurrentStderr(logging.StreamHandler):
        # the stderr of the moment (a test runner swaps it per call), not the first one
        @property
        def stream(self):
            return sys.stderr

        @stream.setter
        def stream(self, _value):
            pass

    logger = logging.getLogger(name)
    if not logger.handlers:
        handler = _CurrentStderr()
        handler.setFormatter(logging.Formatter("note: %(message)s"))
        logger.addHandler(handler)
        logger.setLevel(logging.INFO)
        logger.propagate = False


class _BoundaryGroup(LazyGroup):
    """The top-level group: runs the command inside the error and warning boundary."""

    def invoke(self, ctx: click.Context) -> Any:
        """Run the subcommand; Ctrl-C leaves as :class:`_Interrupted`."""
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt as exc:
            raise _Interrupted() from exc

    def main(self, args: Any = None, prog_name: str | None = None,
             complete_var: str | None = None, standalone_mode: bool = True,
             **extra: Any) -> Any:
        """Run the command line; see the module docstring for the outcome classes.

        Parameters
        ----------
        args : list of str, optional
            Arguments (default ``sys.argv[1:]``).
        prog_name : str, optional
            Program name in messages.
        complete_var : str, optional
            Shell-completion variable (click).
        standalone_mode : bool
            Exit the process with the status (default), else return it.
        **extra
            Passed to :meth:`click.Group.make_context`.

        Returns
        -------
        int
            The exit status (only when ``standalone_mode`` is False).
        """
        _harden(self)
        if sys.stderr.isatty():
            _show_notes("driveid.compile")
        _show_notes("driveid.cost")
        argv = list(sys.argv[1:] if args is None else args)
        debug = "--debug" in argv[:_first_command(argv, self)]
        status = 0
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                rv = super().main(argv, prog_name, complete_var, standalone_mode=False,
                                  **extra)
                status = rv if isinstance(rv, int) and not isinstance(rv, bool) else 0
            except SystemExit as exc:  # clean_errors, ctx.exit
                code = exc.code
                status = code if isinstance(code, int) else (0 if code is None else 1)
                if not isinstance(code, (int, type(None))):
                    click.echo(f"error: {_one_line(code)}", err=True)
            except click.Abort as exc:
                if debug:
                    traceback.print_exception(exc, file=sys.stderr)
                if isinstance(exc.__context__, EOFError):  # click turns EOFError into Abort
                    line, status = _error_line(exc.__context__)
                    click.echo(line, err=True)
                else:
                    click.echo("error: interrupted (Ctrl-C); files being written were not "
                               "completed and are left as they were", err=True)
                    status = EXIT_INTERRUPTED
            except (KeyboardInterrupt, _Interrupted) as exc:
                if debug:
                    traceback.print_exception(exc, file=sys.stderr)
                click.echo("error: interrupted (Ctrl-C); files being written were not "
                           "completed and are left as they were", err=True)
                status = EXIT_INTERRUPTED
            except Exception as exc:
                if debug:
                    traceback.print_exception(exc, file=sys.stderr)
                line, status = _error_line(exc)
                if line:
                    click.echo(line, err=True)
                elif isinstance(exc, click.UsageError) and exc.ctx is not None:
                    click.echo(exc.ctx.get_help(), err=True)
            finally:
                seen: set[str] = set()
                for w in caught:
                    line = _warning_line(w)
                    if line is not None and line not in seen:
                        seen.add(line)
                        click.echo(line, err=True)
        if standalone_mode:
            sys.exit(status)
        return status


def _first_command(argv: list[str], group: click.Group) -> int:
    """Index of the first subcommand name in ``argv`` (global options come before it)."""
    names = set(group.commands) | set(getattr(group, "lazy_commands", {}))
    for i, arg in enumerate(argv):
        if arg in names:
            return i
    return len(argv)


# Subcommands: "name": ("module:object", "short help"). Imported only when run or when their
# own --help is shown, so `driveid --help` does not pay for scipy, numba or matplotlib
# (tests/test_cli_lazy.py checks each short help against the command's docstring).
_C = "driveid.commands."
_TOP = {
    "simulate": ("driveid.cli:simulate", "Simulate systems and write record files."),
    "identify": ("driveid.cli:identify", "Identify parameters from record files."),
    "inspect": (_C + "inspect:inspect_command", "Show what driveid reads from a file."),
    "validate": (_C + "validate:validate_command",
                 "Simulate an identified model over records: fit %, residuals."),
    "report": (_C + "report:report_command", "Write a self-contained HTML report."),
    "pho": (_C + "pho:pho_group", "Parametric harmonic oscillation campaigns."),
    "excite": (_C + "excite:excite_command", "Write an excitation signal (t,u)."),
    "track": (_C + "track:track_command", "Track friction parameters along a long record."),
    "catalog": (_C + "catalog:catalog_group", "Catalogue of identifications (SQLite/PostgreSQL)."),
    "blueprint": (_C + "health:blueprint_group", "Blueprints of healthy axes per machine type."),
    "health": (_C + "health:health_command", "Drift test and verdict of one axis."),
    "fleet": (_C + "fleet:fleet_group", "Identify many records on Dask; simulated fleets."),
    "demo": (_C + "demo:demo_command", "Simulate, identify and report a free decay."),
    "warmup": (_C + "warmup:warmup_command", "Compile and cache the simulation kernels now."),
}
_SIMULATE = {
    "free-decay": (_C + "logdec:free_decay_command", "Exact free decay with friction."),
    "drive": (_C + "drive:drive_command", "Lumped multi-body drive from TOML or a preset."),
    "contour": (_C + "contour:simulate_contour_command",
                "Circular contour test (ball bar) of two feed axes under PID control."),
}
_IDENTIFY = {
    "auto": (_C + "auto:auto_command",
             "Recognise the test in FILES and identify with what applies."),
    "logdec": (_C + "logdec:logdec_command",
               "Free decay: friction, damping, stiffness (output error or peaks)."),
    "hilbert": (_C + "instantaneous:hilbert_command",
                "Instantaneous frequency and damping (Hilbert)."),
    "wavelet": (_C + "instantaneous:wavelet_command",
                "Instantaneous frequency and damping (Morlet wavelet)."),
    "idim": (_C + "friction:idim_command", "Inverse dynamic model by least squares (IDIM)."),
    "friction-map": (_C + "friction:friction_map_command",
                     "Friction against velocity from steady or any motion."),
    "breakaway": (_C + "static:breakaway_command", "Breakaway force from ramps."),
    "loop": (_C + "static:loop_command",
             "Presliding or backlash from force-displacement loops."),
    "static-stiffness": (_C + "static:static_stiffness_command",
                         "Static stiffness from a force-displacement record."),
    "step": (_C + "static:step_command", "Step response: frequency and damping."),
    "forced": (_C + "forced:forced_command", "Forced response: J, C, K from sine runs."),
    "envelope": (_C + "forced:envelope_command", "Viscous vs Coulomb envelope damping."),
    "transfer": (_C + "transfer:transfer_command",
                 "Linear drive model: command to speed or position (TF, two-mass)."),
    "drive": (_C + "identify_drive:drive_command",
              "Fit the lumped drive of CONFIG (TOML) to motor and load records."),
    "subsystems": (_C + "identify_drive:subsystems_command",
                   "Fit sections A, A+B, A+B+C; each part as their difference."),
    "contour": (_C + "contour:identify_contour_command",
                "Circle test: each axis's Coulomb, viscous friction and backlash gap."),
}


@click.group(cls=_BoundaryGroup, lazy_commands=_TOP)
@click.version_option(__version__, prog_name="driveid")
@click.option("--debug", is_flag=True,
              help="Show the Python traceback of an error (for bug reports).")
def cli(debug: bool) -> None:
    """driveid: model and identify friction, backlash and compliance in machine drives."""


@click.group(cls=LazyGroup, lazy_commands=_SIMULATE)
def simulate() -> None:
    """Simulate systems and write record files."""


@click.group(cls=LazyGroup, lazy_commands=_IDENTIFY)
def identify() -> None:
    """Identify parameters from record files."""


def main() -> None:
    """Entry point of the ``driveid`` script: run the command line inside the boundary."""
    try:
        cli.main(prog_name="driveid")
    except KeyboardInterrupt:  # pragma: no cover - Ctrl-C between boundary and exit
        sys.stderr.write("error: interrupted (Ctrl-C)\n")
        sys.exit(EXIT_INTERRUPTED)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
