"""driveid: model and identify friction, backlash with impact and elastic compliance in drives.

Implements and extends J. A. de Marchi, "Modeling of dynamic friction, impact backlash and
elastic compliance nonlinearities in machine tools", PhD thesis, RPI, 1998.

Sign conventions (stated once, used everywhere)
-----------------------------------------------
Equation of motion ``J x'' + C(x') x' + K x + F_k(x') = u`` (thesis 2.136), with

* ``C = c_mean + c_delta * sgn(x')``                      (2.155c)
* ``F_k = fk_mean * sgn(x') + fk_delta`` while moving     (2.155b, 2.156)
* static friction ``fs_mean + fs_delta * sgn(applied force)`` (2.155a)

``delta`` terms are signed. Units are SI: x in m or rad, u in N or N·m, t in s.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
