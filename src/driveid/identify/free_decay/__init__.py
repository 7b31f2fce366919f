"""Free decays: the record the classifier calls ``free-decay`` (thesis §2.2.6).

* :mod:`~driveid.identify.free_decay.output_error` — the whole-record fit (default of
  ``identify logdec``; near the Cramér–Rao bound), with its starts, structures and verdict in
  the ``_free_decay_*`` and ``_free_response`` modules;
* :mod:`~driveid.identify.free_decay.logdec` — the thesis's peak log decrement;
* :mod:`~driveid.identify.free_decay.hilbert`, :mod:`~driveid.identify.free_decay.wavelet`,
  :mod:`~driveid.identify.free_decay.backbone`,
  :mod:`~driveid.identify.free_decay.envelope_friction` — damping and stiffness against amplitude.

Imports only :mod:`driveid.identify.core`.
"""
