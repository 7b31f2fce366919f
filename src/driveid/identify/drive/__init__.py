"""The whole drive as one model: motor, backlash, shaft and load (thesis ch. 3, §5.4).

* :mod:`~driveid.identify.drive.drive_fit` (model in ``_drive_model``, starts in
  ``_drive_starts``) — the lumped multi-body fit to motor and load records;
* :mod:`~driveid.identify.drive.subsystems` — the thesis's subsystem separation.

Imports :mod:`driveid.identify.core` and :mod:`driveid.identify.free_decay` (the encoder
quantum).
"""
