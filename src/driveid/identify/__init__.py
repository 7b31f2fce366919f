"""Identification methods, one module each; every estimator returns an :class:`Estimate`."""

from driveid.identify.estimate import Estimate, Parameter

__all__ = ["Estimate", "Parameter"]
