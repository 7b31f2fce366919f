"""Parametric harmonic oscillation under delayed PD feedback (thesis §2.2.7).

* :mod:`~driveid.identify.pho.peaks` — the thesis's peak analysis of runs and campaigns;
* :mod:`~driveid.identify.pho.pho_fit` — the whole-campaign output-error fit
  (core in ``_pho_fit_core``).

Imports :mod:`driveid.identify.core` and :mod:`driveid.identify.free_decay`.
"""
