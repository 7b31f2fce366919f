"""Subsystem separation (thesis §4.1, Table 5.2): parts as differences of section fits."""

from __future__ import annotations

import math

import pytest

from driveid.errors import ConfigError
from driveid.identify.core.estimate import Estimate, Parameter
from driveid.identify.drive.subsystems import estimate_subsystems, subsystem_differences


def _section(j, se):
    return Estimate("drive-oe", {"body1.J": Parameter(j, se, "kg·m²"),
                                 "body1.K": Parameter(0.0, math.nan, "N·m/rad", fixed=True)})


def test_parts_are_differences_with_independent_errors():
    # the published cumulative inertias of Table 5.2 with made-up standard errors
    out = subsystem_differences([("A", _section(0.0115355, 3e-5)),
                                 ("B", _section(0.0150626, 4e-5)),
                                 ("C", _section(0.0339399, 1e-4))])
    # closed form: differences of the published columns (the preset's bodies B and C)
    assert out.value("B.J") == pytest.approx(0.0035271, abs=1e-12)
    assert out.value("C.J") == pytest.approx(0.0188773, abs=1e-12)
    assert out.stderr("C.J") == pytest.approx(math.hypot(1e-4, 4e-5), rel=1e-12)
    assert out.value("A+B+C.J") == 0.0339399
    assert out["B.K"].fixed and math.isnan(out.stderr("B.K"))  # given minus given


def test_manifest_errors_name_the_problem(tmp_path):
    path = tmp_path / "m.toml"
    path.write_text('[[section]]\nname = "A"\nconfig = "a.toml"\nfiles = ["a.csv"]\n')
    with pytest.raises(ConfigError, match="two or more"):
        estimate_subsystems(path)
    path.write_text('[[section]]\nname = "A"\nconfig = "a.toml"\nfiles = ["a.csv"]\n'
                    'delay = 1\n[[section]]\nname = "B"\nconfig = "b.toml"\nfiles = []\n')
    with pytest.raises(ConfigError, match="unknown key"):
        estimate_subsystems(path)
    with pytest.raises(ConfigError, match="cannot read"):
        estimate_subsystems(tmp_path / "missing.toml")
