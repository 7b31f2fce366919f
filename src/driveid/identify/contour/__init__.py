"""The circular contour test of two feed axes (thesis §6.1).

* :mod:`~driveid.identify.contour.circle` — friction and backlash per axis from the axes'
  positions;
* :mod:`~driveid.identify.contour.ballbar` — the same from a ball bar's radial deviation.

Imports :mod:`driveid.identify.core` and :mod:`driveid.identify.friction` (IDIM starts).
"""
