"""Identification methods, grouped as the test-shape classifier sees records.

Layers (imports point down only; checked by ``tests/test_layers.py``):

1. :mod:`~driveid.identify.core` — :class:`Estimate`, noise models, adequacy, plausibility;
2. :mod:`~driveid.identify.free_decay` and :mod:`~driveid.identify.friction`;
3. :mod:`~driveid.identify.pho` (uses free decays) and :mod:`~driveid.identify.drive`;
4. :mod:`~driveid.identify.forced` (uses PHO's delay factors) and
   :mod:`~driveid.identify.contour` (uses friction);
5. :mod:`~driveid.identify.crlb` (bounds of the free-decay and drive fits) and
   :mod:`~driveid.identify.auto` with its classifier ``_shape`` — on top.

Every estimator returns an :class:`Estimate`; the public functions are ``driveid.<name>``.
"""

from driveid.identify.core.estimate import Estimate, Parameter

__all__ = ["Estimate", "Parameter"]
