"""driveid: model and identify friction, backlash with impact and elastic compliance in drives.

Implements and extends J. A. de Marchi, "Modeling of dynamic friction, impact backlash and
elastic compliance nonlinearities in machine tools", PhD thesis, RPI, 1998.

Main entry points (imported on first use, so ``import driveid`` stays fast)
---------------------------------------------------------------------------
Records and files
    :class:`Record`, :func:`read_record`, :func:`write_record`
Identification (each returns an :class:`Estimate` with standard errors)
    :func:`identify_auto` (recognise the test shape, run what applies, keep the best),
    :func:`estimate_output_error` (whole-record free-decay fit, the default),
    :func:`estimate_log_decrement` (peaks, thesis 2.166-2.175),
    :func:`estimate_hilbert`, :func:`estimate_wavelet`, :func:`estimate_pho_campaign`,
    :func:`estimate_forced_response`, :func:`estimate_idim`, :func:`estimate_friction_map`,
    :func:`estimate_transfer` (command to speed or position: transfer function, two-mass)
Validation
    :func:`compare` (simulate the identified model over a record: fit %, residuals)
Simulation
    :func:`simulate_free_decay`, :func:`simulate_drive`, :func:`simulate_lugre_oscillator`,
    :class:`OscillatorParams`, :class:`DriveParams`, :class:`BodyParams`
Reports
    :func:`write_report` (self-contained HTML)

Sign conventions (stated once, used everywhere)
-----------------------------------------------
Equation of motion ``J x'' + C(x') x' + K x + F_k(x') = u`` (thesis 2.136), with

* ``C = c_mean + c_delta * sgn(x')``                      (2.155c)
* ``F_k = fk_mean * sgn(x') + fk_delta`` while moving     (2.155b, 2.156)
* static friction ``fs_mean + fs_delta * sgn(applied force)`` (2.155a)

``delta`` terms are signed. Units are SI: x in m or rad, u in N or N·m, t in s.

Examples
--------
>>> import driveid
>>> "read_record" in driveid.__all__
True
"""

from __future__ import annotations

import signal
import sys
from typing import Any

from driveid._lazy_exports import lazy_exports


def _interrupted_while_starting(signum: int, frame: Any) -> None:  # pragma: no cover
    """Ctrl-C before the command line is loaded: one line and exit 130, not a traceback."""
    sys.stderr.write("error: interrupted (Ctrl-C) while starting; nothing was done\n")
    raise SystemExit(130)


# Only the `driveid` script, never a library user's process; driveid.cli restores the default
# handler (it recognises this function's name) once its imports are done.
if sys.argv and sys.argv[0].endswith("driveid"):
    try:
        signal.signal(signal.SIGINT, _interrupted_while_starting)
    except ValueError:  # not the main thread
        pass

__version__ = "0.2.0"

# Public name -> module that defines it; resolved lazily (PEP 562) so that the command line
# and ``import driveid`` do not pay for scipy, numba or matplotlib until they are used.
_EXPORTS = {
    "Record": "driveid.io",
    "read_record": "driveid.io",
    "write_record": "driveid.io",
    "Estimate": "driveid.identify.core.estimate",
    "Parameter": "driveid.identify.core.estimate",
    "identify_auto": "driveid.identify.auto",
    "estimate_output_error": "driveid.identify.free_decay.output_error",
    "estimate_drive": "driveid.identify.drive.drive_fit",
    "DriveRecord": "driveid.identify.drive.drive_fit",
    "estimate_subsystems": "driveid.identify.drive.subsystems",
    "estimate_log_decrement": "driveid.identify.free_decay.logdec",
    "estimate_hilbert": "driveid.identify.free_decay.hilbert",
    "estimate_wavelet": "driveid.identify.free_decay.wavelet",
    "estimate_pho_campaign": "driveid.identify.pho.peaks",
    "estimate_forced_response": "driveid.identify.forced.forced",
    "estimate_forced_friction": "driveid.identify.forced.forced_friction",
    "estimate_idim": "driveid.identify.friction.idim",
    "estimate_friction_map": "driveid.identify.friction.friction_map",
    "estimate_transfer": "driveid.identify.forced.transfer",
    "compare": "driveid.validate",
    "simulate_free_decay": "driveid.sim",
    "simulate_drive": "driveid.sim",
    "simulate_lugre_oscillator": "driveid.sim",
    "OscillatorParams": "driveid.sim",
    "DriveParams": "driveid.sim",
    "BodyParams": "driveid.sim",
    "write_report": "driveid.report.html",
}

__all__ = ["__version__", *_EXPORTS]


__getattr__, __dir__ = lazy_exports('driveid', globals(), _EXPORTS)
