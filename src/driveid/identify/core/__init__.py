"""The shared core of every estimator (bottom layer: imports nothing else of ``identify``).

* :mod:`~driveid.identify.core.estimate` — :class:`Estimate` and :class:`Parameter`, the one
  result shape;
* :mod:`~driveid.identify.core._noise` — AR(p) noise models, prewhitening, Newey–West;
* :mod:`~driveid.identify.core._adequacy` — whiteness, residual–input correlation, nested
  structures by BIC;
* :mod:`~driveid.identify.core._plausibility` — physically valid results (bounds, warnings);
* :mod:`~driveid.identify.core._expressions` — regressor expressions of the inverse model.
"""
