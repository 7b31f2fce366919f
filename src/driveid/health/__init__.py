"""Blueprints of machine types and drift tests of axes (de Marchi 1998, §6.1).

See :func:`driveid.health.make_blueprint`, :func:`driveid.health.assess_axis` and
``docs/fleet.md``.
"""

from driveid.health.blueprint import (
    BLUEPRINT_SCHEMA,
    Blueprint,
    BlueprintParameter,
    make_blueprint,
    read_blueprint,
    write_blueprint,
)
from driveid.health.drift import (
    AxisHealth,
    ParameterHealth,
    assess_axis,
    cusum_threshold,
    level_threshold,
)

__all__ = [
    "BLUEPRINT_SCHEMA",
    "Blueprint",
    "BlueprintParameter",
    "make_blueprint",
    "read_blueprint",
    "write_blueprint",
    "AxisHealth",
    "ParameterHealth",
    "assess_axis",
    "cusum_threshold",
    "level_threshold",
]
