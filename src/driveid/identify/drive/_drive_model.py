"""The lumped drive as a function of named parameters, for :mod:`driveid.identify.drive.drive_fit`.

What a drive fit *is*, below the estimator: the measured record of a drive
(:class:`DriveRecord`), the TOML names of the drive's scalar parameters (``body1.J``,
``link1.gap_plus``, ``feedback.delay``, ``body2.x0`` ...) with their units and physical
bounds, a :class:`~driveid.sim.drive_types.DriveParams` rebuilt from values of some of them,
the simulated channels of many parameter vectors in one
:func:`~driveid.sim.batch.simulate_drive_batch` call, their central-difference Jacobian,
and the drive written back as TOML that ``driveid simulate drive`` reads.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from driveid.errors import IdentificationError, ParameterError, SimulationError
from driveid.sim.drive_types import BacklashLink, BodyParams, DriveParams, ShaftLink

__all__ = ["DriveRecord", "parameter_names", "parameter_unit", "lower_bound"]

_CHANNEL = re.compile(r"^([xv])([1-9][0-9]*)$")
_BODY_FIELDS = ("J", "K", "c_mean", "c_delta", "fk_mean", "fk_delta", "fs_mean", "fs_delta")
# only on a body with a Stribeck map / rising static friction (BodyParams.stribeck, dwell_gamma)
_STRIBECK_FIELDS = ("v_s", "v_s_delta", "stribeck_exponent")
_MEMORY_FIELDS = ("memory",)  # frictional memory (Eq. 2.12) acts on the Stribeck part only
_DWELL_FIELDS = ("dwell_gamma", "dwell_kappa")
_SHAFT_FIELDS = ("k", "c")
_BACKLASH_FIELDS = ("gap_plus", "gap_minus", "k", "c")
_FEEDBACK_FIELDS = ("P", "D", "delay")
_STATE_FIELDS = ("x0", "v0")
# relative central-difference step: large enough that the located event times move by many
# times their location tolerance, small enough that the truncation error (step²) is 1e-6
_REL_STEP = 1e-3
# step pairs of the local Jacobian (DriveProblem.local_jacobian), tried in turn: a column is
# taken where a pair agrees; 1e-7 still moves event times by ~1e4 times their location
# tolerance (~1e-12 s), and the test bed's columns agree to 1e-6 from 1e-5 to 1e-7
_LOCAL_PAIRS = ((1e-5, 1e-6), (1e-4, 1e-5), (1e-6, 1e-7))
_NAME = re.compile(r"^(body|link)([1-9][0-9]*)\.(\w+)$|^feedback\.(P|D|delay)$")


@dataclass(frozen=True)
class DriveRecord:
    """One measured run of a drive: time, input and any subset of body channels.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Uniform sample times [s].
    channels : mapping of str to ndarray, shape (n,)
        Measured channels named as ``driveid simulate drive`` writes them: ``x1`` (position
        of body 1) [rad or m], ``v1`` (its velocity) [rad/s or m/s], ``x2`` ...
    u : ndarray, shape (n,) or None
        Torque or force on the input body [N·m or N] (open loop); None under feedback.
    meta : mapping
        Provenance (source file, columns).
    """

    t: np.ndarray
    channels: Mapping[str, np.ndarray]
    u: np.ndarray | None = None
    meta: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        from driveid.errors import RecordError

        t = np.asarray(self.t, dtype=float)
        if t.ndim != 1 or t.size < 10 or not np.all(np.isfinite(t)):
            raise RecordError(f"a drive record needs at least 10 finite sample times; got "
                              f"shape {t.shape}")
        dt = np.diff(t)
        if np.any(dt <= 0) or np.max(np.abs(dt - dt.mean())) > 1e-6 * dt.mean():
            raise RecordError("the drive fit needs uniform sampling (the simulator samples "
                              "at fs); resample the record first; got a jittered or "
                              "non-increasing time column")
        chans = {}
        for name, values in dict(self.channels).items():
            if not _CHANNEL.match(name):
                raise RecordError(f"drive channels are named x1, v1, x2, ... (body counted "
                                  f"from 1); got {name!r}")
            arr = np.asarray(values, dtype=float)
            if arr.shape != t.shape or not np.all(np.isfinite(arr)):
                raise RecordError(f"channel {name} must be finite with one value per sample "
                                  f"({t.size}); got shape {arr.shape}")
            chans[name] = arr
        if not chans:
            raise RecordError("a drive record needs at least one measured channel (x1, v1, "
                              "x2 ...); got none")
        u = None
        if self.u is not None:
            u = np.asarray(self.u, dtype=float)
            if u.shape != t.shape or not np.all(np.isfinite(u)):
                raise RecordError(f"u must be finite with one value per sample ({t.size}); "
                                  f"got shape {u.shape}")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "channels", chans)
        object.__setattr__(self, "u", u)
        object.__setattr__(self, "meta", dict(self.meta))

    @property
    def fs(self) -> float:
        """Sampling rate [Hz]."""
        return float((self.t.size - 1) / (self.t[-1] - self.t[0]))

    @property
    def n(self) -> int:
        """Number of samples [-]."""
        return int(self.t.size)

    @property
    def columns(self) -> tuple[str, ...]:
        """The record's columns: ``t``, the channels and ``u`` when present."""
        return ("t", *self.channels, *(("u",) if self.u is not None else ()))

    @property
    def units(self) -> dict[str, str]:
        """Unit of each column as read (``meta["units"]``; ``t`` in s) [-]."""
        return {"t": "s", **dict(self.meta.get("units") or {})}

    @classmethod
    def from_result(cls, result: Any, channels: Sequence[str] = ("x1",), *,
                    input_body: int | None = 0) -> DriveRecord:
        """Return the channels of a simulated drive as a record (tests, benchmarks).

        Parameters
        ----------
        result : DriveResult
            From :func:`driveid.sim.simulate_drive`.
        channels : sequence of str
            Which channels to keep (``x1``, ``v2`` ...).
        input_body : int or None
            0-based body whose row of the command is ``u`` (None: no ``u``).

        Returns
        -------
        DriveRecord
            The record (noise-free).
        """
        chans = {}
        for name in channels:
            m = _CHANNEL.match(name)
            if m is None:
                raise ParameterError(f"channels are named x1, v1, x2 ...; got {name!r}")
            arr = result.x if m.group(1) == "x" else result.v
            chans[name] = arr[int(m.group(2)) - 1]
        u = None
        if input_body is not None:
            cmd = np.asarray(result.command)
            u = cmd if cmd.ndim == 1 else cmd[input_body]
        return cls(t=result.t, channels=chans, u=u, meta={"source": "simulate_drive"})


def channel_index(name: str) -> tuple[str, int]:
    """Return ``("x" or "v", 0-based body)`` of a channel name such as ``x2``."""
    m = _CHANNEL.match(name)
    return m.group(1), int(m.group(2)) - 1


def parameter_names(params: DriveParams, *, states: bool = True) -> list[str]:
    """Return the TOML names of every scalar parameter of a drive (bodies counted from 1).

    Parameters
    ----------
    params : DriveParams
        The drive.
    states : bool
        Include the initial states ``bodyI.x0``, ``bodyI.v0`` of the unlocked bodies.

    Returns
    -------
    list of str
        ``body1.J``, ``body1.K`` ..., ``link1.k`` ..., ``feedback.P`` ..., ``body1.x0`` ...
    """
    names = []
    for i, b in enumerate(params.bodies):
        if b.locked:
            continue
        names += [f"body{i + 1}.{f}" for f in _body_fields(b)]
    for j, ln in enumerate(params.links):
        if isinstance(ln, ShaftLink):
            names += [f"link{j + 1}.{f}" for f in _SHAFT_FIELDS]
        elif isinstance(ln, BacklashLink):
            names += [f"link{j + 1}.{f}" for f in _BACKLASH_FIELDS]
    if params.feedback is not None:
        names += [f"feedback.{f}" for f in _FEEDBACK_FIELDS]
    if states:
        names += [f"body{i + 1}.{f}" for i, b in enumerate(params.bodies) if not b.locked
                  for f in _STATE_FIELDS]
    return names


def _body_fields(b: BodyParams) -> tuple[str, ...]:
    """Scalar parameters of a body: friction levels, then its Stribeck, memory, dwell ones."""
    fields = _BODY_FIELDS
    if b.stribeck is not None:
        # the exponent of the Lorentzian map is not used: not a parameter of it
        fields += _STRIBECK_FIELDS if b.stribeck == "bo_pavelescu" else _STRIBECK_FIELDS[:2]
        fields += _MEMORY_FIELDS
    if b.dwell_gamma is not None:
        fields += _DWELL_FIELDS
    return fields


def parameter_unit(name: str, units: str = "rad") -> str:
    """Return the SI unit of a parameter name.

    Parameters
    ----------
    name : str
        TOML name, e.g. ``body1.J``, ``link1.gap_plus``.
    units : {"rad", "m"}
        Rotational or translational drive.

    Returns
    -------
    str
        The unit, e.g. ``"kg·m²"``.
    """
    field_name = name.rsplit(".", 1)[1]
    rot = units == "rad"
    table = {
        "J": "kg·m²" if rot else "kg", "K": "N·m/rad" if rot else "N/m",
        "k": "N·m/rad" if rot else "N/m", "P": "N·m/rad" if rot else "N/m",
        "c_mean": "N·m·s/rad" if rot else "N·s/m", "c_delta": "N·m·s/rad" if rot else "N·s/m",
        "c": "N·m·s/rad" if rot else "N·s/m", "D": "N·m·s/rad" if rot else "N·s/m",
        "gap_plus": units, "gap_minus": units, "x0": units,
        "v0": "rad/s" if rot else "m/s", "delay": "s", "memory": "s",
        "v_s": "rad/s" if rot else "m/s", "v_s_delta": "rad/s" if rot else "m/s",
        "stribeck_exponent": "-", "dwell_kappa": "-", "dwell_gamma": "s**kappa",
    }
    return table.get(field_name, "N·m" if rot else "N")


def lower_bound(name: str) -> float:
    """Return the physical lower bound of a parameter.

    Parameters
    ----------
    name : str
        TOML name, e.g. ``body1.J``.

    Returns
    -------
    float
        0 for J, K, viscous and kinetic/static friction means, link k and c, gaps, the
        delay, the frictional memory and the Stribeck and dwell constants; ``-inf`` for
        signed asymmetries, gains and initial states.
    """
    field_name = name.rsplit(".", 1)[1]
    if field_name in ("c_delta", "fk_delta", "fs_delta", "v_s_delta", "x0", "v0", "P", "D"):
        return -math.inf
    return 0.0


def get_value(params: DriveParams, x0: np.ndarray, v0: np.ndarray, name: str) -> float:
    """Return the value of a named parameter of a drive and its initial state."""
    kind, index, field_name = _split(name, params)
    if field_name == "x0":
        return float(x0[index])
    if field_name == "v0":
        return float(v0[index])
    owner = {"body": params.bodies, "link": params.links}.get(kind)
    obj = params.feedback if kind == "feedback" else owner[index]
    return float(getattr(obj, field_name))


def _split(name: str, params: DriveParams) -> tuple[str, int, str]:
    m = _NAME.match(name)
    if m is None:
        raise ParameterError(f"parameters are named as in the TOML, e.g. body1.J, link1.k, "
                             f"feedback.delay, body2.x0; got {name!r}")
    if m.group(4):
        if params.feedback is None:
            raise ParameterError(f"{name} needs a [feedback] table in the drive; got none")
        return "feedback", 0, m.group(4)
    kind, index, field_name = m.group(1), int(m.group(2)) - 1, m.group(3)
    count = params.n_bodies if kind == "body" else len(params.links)
    if index >= count:
        raise ParameterError(f"{name}: the drive has {count} {kind}(s); got {kind} "
                             f"{index + 1}")
    if kind == "body":
        allowed = _body_fields(params.bodies[index]) + _STATE_FIELDS
    else:
        ln = params.links[index]
        allowed = (_SHAFT_FIELDS if isinstance(ln, ShaftLink) else
                   _BACKLASH_FIELDS if isinstance(ln, BacklashLink) else ())
    if field_name not in allowed:
        raise ParameterError(f"{name}: {kind} {index + 1} has the parameters "
                             f"{list(allowed)}; got {field_name!r}")
    return kind, index, field_name


def check_names(params: DriveParams, names: Sequence[str]) -> list[str]:
    """Validate estimated parameter names (raise ParameterError naming the bad one)."""
    out = []
    for name in names:
        kind, index, _ = _split(name, params)
        if kind == "body" and params.bodies[index].locked:
            raise ParameterError(f"{name}: body {index + 1} is locked; unlock it or drop "
                                 f"{name}")
        if name in out:
            raise ParameterError(f"{name} is named twice in the estimated parameters")
        out.append(name)
    return out


def _follows_kinetic(b: BodyParams) -> tuple[bool, bool]:
    """Whether the static band is the kinetic one (then it moves with fk_mean, fk_delta)."""
    eps = 1e-12 * max(1.0, abs(b.fk_mean) + abs(b.fk_delta))
    return (abs(b.fs_mean - b.fk_mean - b.ripple_amplitude) <= eps,
            abs(b.fs_delta - b.fk_delta) <= eps)


def with_values(params: DriveParams, x0: np.ndarray, v0: np.ndarray,
                values: Mapping[str, float]) -> tuple[DriveParams, np.ndarray, np.ndarray]:
    """Return the drive and initial state with some named parameters replaced.

    A static band equal to the kinetic one in ``params`` follows the kinetic values.
    """
    bodies = [dict() for _ in params.bodies]
    links = [dict() for _ in params.links]
    feedback: dict = {}
    x0, v0 = x0.copy(), v0.copy()
    for name, value in values.items():
        kind, index, field_name = _split(name, params)
        if field_name == "x0":
            x0[index] = value
        elif field_name == "v0":
            v0[index] = value
        elif kind == "body":
            bodies[index][field_name] = float(value)
        elif kind == "link":
            links[index][field_name] = float(value)
        else:
            feedback[field_name] = float(value)
    new_bodies = []
    for b, change in zip(params.bodies, bodies, strict=True):
        if change:
            mean, delta = _follows_kinetic(b)
            if mean and "fs_mean" not in change:
                change["fs_mean"] = None
            if delta and "fs_delta" not in change:
                change["fs_delta"] = None
            b = dataclasses.replace(b, **change)
        new_bodies.append(b)
    new_links = [dataclasses.replace(ln, **c) if c else ln
                 for ln, c in zip(params.links, links, strict=True)]
    fb = dataclasses.replace(params.feedback, **feedback) if feedback else params.feedback
    return (DriveParams(bodies=tuple(new_bodies), links=tuple(new_links), feedback=fb,
                        motor=params.motor), x0, v0)


class DriveProblem:
    """Simulated channels of a drive as a function of a scaled parameter vector.

    ``theta = scale * z``; :meth:`outputs` simulates many ``z`` for one record in one batch
    call (threads); :meth:`jacobian` stacks central differences.
    """

    def __init__(self, base: DriveParams, x0: np.ndarray, v0: np.ndarray,
                 names: Sequence[str], scale: np.ndarray, record: DriveRecord,
                 input_body: int | None, torque: np.ndarray | None = None,
                 parallel: bool = True, progress: Any = None,
                 built: dict | None = None) -> None:
        self.base, self.x0, self.v0 = base, np.asarray(x0, float), np.asarray(v0, float)
        self.names, self.scale = list(names), np.asarray(scale, float)
        # initial states are set on the arrays; the drive itself is built once per value
        # of the other parameters, in a cache that the problems of one fit may share (the
        # pieces of a record: every piece's Jacobian perturbs the same shared parameters)
        self._states = [(j, n.rsplit(".", 1)[1] == "x0", _split(n, base)[1])
                        for j, n in enumerate(self.names) if n.endswith((".x0", ".v0"))]
        self._drive_cols = [j for j, n in enumerate(self.names)
                            if not n.endswith((".x0", ".v0"))]
        self._built = {} if built is None else built
        self.record = record
        self.channels = list(record.channels)
        n, nb = record.t.size, base.n_bodies
        grid = np.zeros((nb, n))
        if torque is not None:
            grid += np.asarray(torque, float).reshape(nb, -1)
        if input_body is not None and record.u is not None:
            grid[input_body] += record.u
        self.torque = grid
        self.parallel = parallel
        self.progress = progress  # called with the simulations of each batch
        self.fs = record.fs
        self.duration = (n - 1) / self.fs
        self.n_sims = 0
        self.n_refused = 0  # trial drives refused unsimulated for their RK4 steps

    def build(self, z: np.ndarray) -> tuple[DriveParams, np.ndarray, np.ndarray]:
        """Return the drive and initial state at scaled values ``z``."""
        theta = np.asarray(z, float) * self.scale
        cols = self._drive_cols
        key = (id(self.base), tuple(self.names[j] for j in cols), theta[cols].tobytes())
        hit = self._built.get(key)
        if hit is not None and hit[0] is self.base:
            params = hit[1]
        else:
            if len(self._built) > 4096:  # a long fit: the early trial drives are not asked again
                self._built.clear()
            params = with_values(self.base, self.x0, self.v0,
                                 {self.names[j]: theta[j] for j in cols})[0]
            self._built[key] = (self.base, params)
        x0, v0 = self.x0.copy(), self.v0.copy()
        for j, is_x, body in self._states:
            (x0 if is_x else v0)[body] = theta[j]
        return params, x0, v0

    def outputs(self, zs: Sequence[np.ndarray]) -> list[np.ndarray]:
        """Simulate each ``z``; return the measured channels, shape (n_channels, n) each."""
        from driveid.sim.batch import simulate_drive_batch

        built = []
        for z in zs:
            try:
                built.append(self.build(z))
            except ParameterError as exc:
                raise IdentificationError(f"the fit reached an unphysical drive ({exc}); "
                                          "start nearer the truth or fix that parameter"
                                          ) from None
        try:
            results = simulate_drive_batch(
                [b[0] for b in built], duration=self.duration, fs=self.fs,
                x0=np.array([b[1] for b in built]), v0=np.array([b[2] for b in built]),
                torque=self.torque, parallel=self.parallel and len(built) > 1)
        except SimulationError as exc:
            raise IdentificationError(f"a trial drive could not be simulated ({exc}); "
                                      "start nearer the truth or fix the contact "
                                      "parameters") from None
        self.n_sims += len(built)
        if self.progress is not None:
            self.progress(len(built))
        n = self.record.t.size
        out = []
        for res in results:
            rows = []
            for name in self.channels:
                kind, body = channel_index(name)
                rows.append((res.x if kind == "x" else res.v)[body][:n])
            arr = np.array(rows)
            if arr.shape[1] != n or not np.all(np.isfinite(arr)):
                raise IdentificationError("a trial drive aborted or diverged before the "
                                          "record's end; start nearer the truth or fix "
                                          "the feedback parameters")
            out.append(arr)
        return out

    def steps(self, z: np.ndarray, rel_step: float = _REL_STEP) -> np.ndarray:
        """Central-difference steps in z (relative, never across a lower bound of 0)."""
        return rel_step * np.maximum(np.abs(z), 1e-2)

    def value_and_jacobian(self, z: np.ndarray, rel_step: float = _REL_STEP,
                           columns: Sequence[int] | None = None,
                           ) -> tuple[np.ndarray, np.ndarray]:
        """Return the channels at ``z`` and their central-difference Jacobian.

        Parameters
        ----------
        z : ndarray, shape (p,)
            Scaled parameters [-].
        rel_step : float
            Relative difference step [-].
        columns : sequence of int, optional
            Differentiate these parameters only (the other columns are nan).

        Returns
        -------
        y : ndarray, shape (n_channels, n)
        jac : ndarray, shape (n_channels, n, p)
        """
        z = np.asarray(z, float)
        cols = list(range(z.size)) if columns is None else list(columns)
        h = self.steps(z, rel_step)
        lower = np.array([lower_bound(n) for n in self.names]) / self.scale
        one_sided = z - h < lower
        zs = [z]
        for j in cols:
            for sign in ((1.0, 2.0) if one_sided[j] else (1.0, -1.0)):
                zj = z.copy()
                zj[j] += sign * h[j]
                zs.append(zj)
        outs = self.outputs(zs)
        jac = np.full(outs[0].shape + (z.size,), np.nan)
        for i, j in enumerate(cols):
            plus, other = outs[1 + 2 * i], outs[2 + 2 * i]
            if one_sided[j]:  # second-order forward difference: z - h would leave the bound
                jac[..., j] = (4.0 * plus - other - 3.0 * outs[0]) / (2.0 * h[j])
            else:
                jac[..., j] = (plus - other) / (2.0 * h[j])
        return outs[0], jac

    def local_jacobian(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return the channels at ``z`` and the local (small-step) Jacobian.

        The fit's step (:data:`_REL_STEP`, 1e-3) straddles the kinks where the number of
        stick or contact events changes; that smoothed secant steers Levenberg–Marquardt
        from far away, but it is not the derivative at the optimum, and where two
        parameters nearly trade (a motor's viscous friction and the loop's delay) a few
        per cent of error in a column halves the weak direction's variance and stops the
        fit short of the minimum. Each column is taken at two small steps (:data:
        `_LOCAL_PAIRS`, first 1e-5 against 1e-6): where they agree within 2 % the column
        is the local derivative; where a kink lies between them the next pair is tried;
        where it keeps growing as the step shrinks (a discontinuity, e.g. a start velocity
        of exactly 0 that separates a stuck start from a sliding one) the fit's secant is
        kept. Measured on the test bed (benchmarks/bench_drive_fit.py, docs/drive-fit.md).

        Returns
        -------
        y : ndarray, shape (n_channels, n)
        jac : ndarray, shape (n_channels, n, p)
        """
        z = np.asarray(z, float)
        cache: dict[float, np.ndarray] = {}
        y = None
        out = np.full(self._shape(z), np.nan)
        pending = list(range(z.size))
        for pair in _LOCAL_PAIRS:
            for step in pair:  # each step's columns once, only for the columns still open
                need = [j for j in pending if step not in cache or np.isnan(
                    cache[step][0, 0, j])]
                if need:
                    y, jac = self.value_and_jacobian(z, step, need)
                    if step in cache:
                        cache[step][..., need] = jac[..., need]
                    else:
                        cache[step] = jac
            big, small = cache[pair[0]], cache[pair[1]]
            for j in list(pending):
                size = np.linalg.norm(small[..., j])
                if size > 0.0 and np.linalg.norm(small[..., j] - big[..., j]) <= 0.02 * size:
                    out[..., j] = small[..., j]
                    pending.remove(j)
            if not pending:
                break
        if pending:
            y, jac = self.value_and_jacobian(z, _REL_STEP, pending)
            out[..., pending] = jac[..., pending]
        return y, out

    def _shape(self, z: np.ndarray) -> tuple[int, int, int]:
        return (len(self.channels), self.record.t.size, z.size)


#: Simulations a fit typically runs per unknown (measured 40-460: the two-body open-loop
#: speed case and the three-body test bed with its growing horizons), for the cost estimate.
_SIMS_PER_UNKNOWN = 200
#: Default budget of RK4 steps of a whole fit: ~150 times the test bed's (6e7), about an
#: hour on one core; a stiff contact on a light body needs 1e11 per second of record.
DEFAULT_FIT_STEPS = 10**10
#: A fit expected to take longer than this [s] is announced before it starts.
ANNOUNCE_SECONDS = 30.0


def check_fit_cost(params: DriveParams, records: Sequence[DriveRecord], n_unknowns: int,
                   max_steps: float | None = DEFAULT_FIT_STEPS, passes: int = 1) -> int:
    """Refuse a fit whose simulations would take more RK4 steps than ``max_steps``.

    Parameters
    ----------
    params : DriveParams
        The drive at the start values.
    records : sequence of DriveRecord
        The measured runs (their durations [s] and rates [Hz]).
    n_unknowns : int
        Parameters and initial states estimated [-].
    max_steps : float or None
        Budget of RK4 steps of the whole fit [-]; None: no budget.
    passes : int
        Whole fits run (``paths`` of :func:`~driveid.identify.drive.drive_fit.
        estimate_drive`) [-].

    Returns
    -------
    int
        The simulations the fit is expected to run [-] (for a progress bar).

    Raises
    ------
    ParameterError
        Over the budget: the message names the steps, the stiffest element and the fix;
        or one simulation would not fit in memory (a feedback delay of days, say).
    """
    from driveid.sim.drive_cost import _duration_words, check_drive_cost, estimate_drive_cost

    costs = [estimate_drive_cost(params, duration=float(r.t[-1] - r.t[0]), fs=r.fs)
             for r in records]
    for r, c in zip(records, costs, strict=True):  # each simulation's memory (issue 28)
        check_drive_cost(c, duration=float(r.t[-1] - r.t[0]), max_steps=None)
    sims = _SIMS_PER_UNKNOWN * (n_unknowns + 1) * int(passes)
    steps = float(sims * sum(c.n_steps for c in costs))
    seconds = sims * sum(c.seconds for c in costs)
    if max_steps is not None and steps > max_steps:
        worst = max(costs, key=lambda c: c.n_steps)
        raise ParameterError(
            f"identify drive: about {steps:.2g} RK4 steps needed (some {sims} simulations of "
            f"{worst.n_steps:.2g} steps: a {worst.step:.2g} s step resolves the stiffest mode, "
            f"{worst.stiffest}, period {worst.period:.2g} s), over the budget of "
            f"{max_steps:.2g} steps (max_steps, CLI --max-steps), about "
            f"{_duration_words(seconds)} of work; soften or fix that element in the start "
            "TOML (lower k, raise J), fit a shorter window (FILE@T0:T1), or raise the budget")
    if seconds > ANNOUNCE_SECONDS:  # long but feasible: say so before the silence (issue 28)
        import logging

        logging.getLogger("driveid.cost").info(
            f"identify drive: about {sims} simulations of {sum(c.n_steps for c in costs):.3g} "
            f"RK4 steps and {params.n_bodies} bodies each, about {_duration_words(seconds)} "
            "on one core (an estimate; the fit may stop sooner or run longer)")
    return sims


def counting(progress: Any, expected: int) -> Any:
    """Turn ``progress(done, expected)`` into a callback that takes each batch's count."""
    done = [0]

    def tick(k: int) -> None:
        done[0] += k
        progress(done[0], expected)

    return tick


def _fmt(value: float) -> str:
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return repr(float(value))


def drive_to_toml(params: DriveParams, *, duration: float | None = None,
                  fs: float | None = None, x0=None, v0=None, units: str = "rad",
                  comments: Mapping[str, str] | None = None) -> str:
    """Return a TOML description of a drive that :mod:`driveid.sim.config` reads back.

    ``comments`` maps parameter names (``body1.J``) to a trailing comment (``± s.e.``).
    """
    comments = dict(comments or {})

    def line(key: str, value: float, name: str) -> str:
        note = comments.get(name)
        return f"{key} = {_fmt(value)}" + (f"  # {note}" if note else "")

    out = ["# drive identified by driveid identify drive; bodies count from 1",
           "# (simulate drive re-runs it; an open-loop input torque is not part of it)", ""]
    for i, b in enumerate(params.bodies):
        out.append("[[body]]")
        for f in ("J", "K", "c_mean", "c_delta", "fk_mean", "fk_delta"):
            out.append(line(f, getattr(b, f), f"body{i + 1}.{f}"))
        mean, delta = _follows_kinetic(b)
        if not mean or not delta:
            out.append(line("fs_mean", b.fs_mean, f"body{i + 1}.fs_mean"))
            out.append(line("fs_delta", b.fs_delta, f"body{i + 1}.fs_delta"))
        if b.locked:
            out.append("locked = true")
        if b.stribeck is not None:
            out.append(f'stribeck = "{b.stribeck}"')
            out += [line(f, getattr(b, f), f"body{i + 1}.{f}")
                    for f in _body_fields(b) if f in _STRIBECK_FIELDS]
            if b.memory > 0.0:
                out.append(line("memory", b.memory, f"body{i + 1}.memory"))
        if b.dwell_gamma is not None:
            out += [line(f, getattr(b, f), f"body{i + 1}.{f}") for f in _DWELL_FIELDS]
        if b.has_ripple:
            out += [f"ripple_amplitude = {_fmt(b.ripple_amplitude)}",
                    f"ripple_period = {_fmt(b.ripple_period)}",
                    f"ripple_phase = {_fmt(b.ripple_phase)}"]
        out.append("")
    for j, ln in enumerate(params.links):
        out.append("[[link]]")
        if ln is None:
            out += ['type = "none"', ""]
            continue
        if isinstance(ln, ShaftLink):
            out.append('type = "shaft"')
            keys = _SHAFT_FIELDS
        else:
            out.append('type = "backlash"')
            keys = _BACKLASH_FIELDS
        out += [line(f, getattr(ln, f), f"link{j + 1}.{f}") for f in keys]
        if isinstance(ln, BacklashLink):
            if ln.allow_tension:
                out.append("allow_tension = true")
            if ln.contact == "restitution":
                out += ['contact = "restitution"', f"restitution = {_fmt(ln.restitution)}",
                        f"rest_velocity = {_fmt(ln.rest_velocity)}"]
        out.append("")
    fb = params.feedback
    if fb is not None:
        out.append("[feedback]")
        out += [line(f, getattr(fb, f), f"feedback.{f}") for f in _FEEDBACK_FIELDS]
        out += [f"body = {fb.body + 1}", f"reference = {_fmt(fb.reference)}",
                f"saturation = {_fmt(fb.saturation)}", f"abort_limit = {_fmt(fb.abort_limit)}",
                ""]
    out.append("[run]")
    if duration is not None:
        out.append(f"duration = {_fmt(duration)}")
    if fs is not None:
        out.append(f"fs = {_fmt(fs)}")
    for key, vals in (("x0", x0), ("v0", v0)):
        if vals is not None:
            out.append(f"{key} = [{', '.join(_fmt(v) for v in vals)}]")
    out.append(f'units = "{units}"')
    return "\n".join(out) + "\n"
