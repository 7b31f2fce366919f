"""Which file column is which record column: names, conventions, and never a silent guess.

Rules (docs/reading.md, "Choosing columns"):

1. A column asked for by its full name is that column (``--position "pos (3)"``); the
   name may be given with its unit (``"x [mm]"``) or in another case when that is unique.
2. A name that fits several columns (a repeated header ``pos``, or ``pos`` for ``pos (5)``,
   ``pos (3)``, ``pos (4)``) is refused with the candidates listed.
3. Columns not asked for are found by their quantity word (:data:`QUANTITY_WORDS`: ``t``,
   ``time``; ``x``, ``position``, ``q``; ``v``, ``speed``, ``dq``, ``qd``; ``u``, ``torque``,
   ``tau`` ...), read from the tokens of the name, so the robot and servo conventions
   ``q2``, ``dq2``, ``ddq2`` (an acceleration, never a record column), ``tau2``,
   ``q2_tau_J_compensate`` (joint 2's torque, a model prediction) and ``pos_measured``,
   ``pos_target`` are understood. Measured columns win over plain ones; targets, commands
   and model predictions are never taken for a position or velocity (a commanded force or
   torque is, as the drive's input, when no measured one exists). Once one column names a
   joint or servo number (``q2``, ``pos (3)``), the others follow that number.
4. Every choice that is not a plain, unique name is shown (a note); several equally good
   candidates are refused with the list.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass

__all__ = ["QUANTITY_WORDS", "ColumnName", "parse_column_name", "rank_candidates"]

#: Record column -> words of a column name that state that quantity (lower case).
QUANTITY_WORDS: dict[str, tuple[str, ...]] = {
    "t": ("t", "time", "zeit", "timestamp", "times", "sec", "seconds", "stamp"),
    "x": ("x", "position", "pos", "weg", "theta", "q", "angle", "winkel", "displacement",
          "disp", "lage", "posistion", "encoder", "enc", "θ", "φ", "phi"),
    "v": ("v", "velocity", "vel", "speed", "omega", "geschwindigkeit", "drehzahl", "dq",
          "qd", "qdot", "dtheta", "thetadot", "dx", "xd", "xdot", "rpm", "ω"),
    "u": ("u", "force", "torque", "tau", "f", "kraft", "moment", "drehmoment", "load",
          "effort", "trq", "tq", "load cell", "loadcell", "τ"),
}
#: Words of an acceleration column: recognised so that it is never read as something else.
ACCELERATION_WORDS = ("ddq", "qdd", "qddot", "acc", "accel", "acceleration", "ddx", "xdd",
                      "alpha", "ddtheta", "α")
# single letters count only as the first word: 'Weg &b_A1' is no acceleration 'a'
_SINGLE = {"t", "x", "q", "v", "u", "f"}
_MEASURED = {"measured", "meas", "msr", "act", "actual", "fb", "feedback", "ist", "present",
             "real", "sensor", "sensed", "encoder", "enc", "obs", "observed"}
_TARGET = {"target", "tgt", "cmd", "command", "commanded", "desired", "des", "ref",
           "reference", "setpoint", "sp", "set", "demand", "soll", "goal", "d", "trajectory",
           "traj", "planned", "plan"}
_PREDICTION = {"pred", "predicted", "prediction", "model", "modelled", "modeled", "est",
               "estimate", "estimated", "sim", "simulated", "compensate", "compensation",
               "comp", "ff", "feedforward", "fit", "fitted", "expected", "hat", "ext",
               "gravity", "grav", "coriolis", "friction", "inertial", "id", "dyn"}
_ROLE_WORDS = {"measured": "measured", "target": "target/commanded",
               "prediction": "model prediction", "plain": "plain"}


@dataclass(frozen=True)
class ColumnName:
    """What a column's name says about it.

    Attributes
    ----------
    name : str
        The column name in the file.
    quantity : {"t", "x", "v", "u", "a"} or None
        Record column it states (``a``: an acceleration, never chosen).
    role : {"measured", "plain", "target", "prediction"}
        Measured signal, a name without role, a target/command, or a model prediction.
    joint : str or None
        Joint, servo or axis number in the name (``q2`` -> ``"2"``, ``pos (3)`` -> ``"3"``).
    exact : bool
        True when the whole name is one quantity word (``position``, ``q``).
    convention : bool
        True when the quantity comes from a robot or servo convention (``q``, ``dq``,
        ``qd``, ``tau``, a joint number) rather than a plain word.
    """

    name: str
    quantity: str | None
    role: str
    joint: str | None
    exact: bool
    convention: bool

    @property
    def role_words(self) -> str:
        """The role in words, for notes."""
        return _ROLE_WORDS[self.role]


_WORD_OF: dict[str, str] = {w: col for col, words in QUANTITY_WORDS.items() for w in words}
_WORD_OF.update({w: "a" for w in ACCELERATION_WORDS})
_ROBOT = {"q", "dq", "qd", "qdot", "ddq", "qdd", "tau"}


def _tokens(name: str) -> list[str]:
    leaf = re.split(r"[./:]", name.strip())[-1] if not re.fullmatch(r".*:\d+", name) else name
    text = leaf.lower().replace("load cell", "loadcell")
    return re.findall(r"[^\W\d_]+|\d+", text)


def parse_column_name(name: str) -> ColumnName:
    """Read the quantity, role and joint number from a column name.

    Parameters
    ----------
    name : str
        A column name as read from the file (without its unit).

    Returns
    -------
    ColumnName
        The reading of the name.

    Examples
    --------
    >>> c = parse_column_name("q2_tau_J_compensate")
    >>> c.quantity, c.role, c.joint
    ('u', 'prediction', '2')
    >>> parse_column_name("dq2").quantity, parse_column_name("pos (3)").joint
    ('v', '3')
    """
    tokens = _tokens(name)
    quantities: list[tuple[int, str]] = []
    for i, tok in enumerate(tokens):
        col = _WORD_OF.get(tok)
        if col is None or (tok in _SINGLE and i > 0):
            continue
        quantities.append((i, col))
    # robot glued joint numbers: 'q2', 'dq2', 'tau2' tokenise as ('q', '2'); 'qd' stays one
    quantity, index = None, -1
    if quantities:
        index, quantity = quantities[-1]  # 'q2_tau_J': joint 2's torque, the last word
    words = set(tokens[index + 1:]) if quantity else set(tokens)
    role = "plain"
    if words & _PREDICTION or set(tokens) & (_PREDICTION - {"id", "dyn"}):
        role = "prediction"
    elif (words | set(tokens[:max(index, 0)])) & (_TARGET - {"d"}) or (
            quantity and "d" in words and tokens[-1] == "d"):
        role = "target"
    elif set(tokens) & _MEASURED:
        role = "measured"
    joint = next((tok for tok in tokens if tok.isdigit()), None)
    exact = len(tokens) == 1 and quantity is not None
    convention = bool(quantity) and (tokens[index] in _ROBOT or (
        joint is not None and tokens.index(joint) == index + 1))
    return ColumnName(name=name, quantity=quantity, role=role, joint=joint, exact=exact,
                      convention=convention)


def rank_candidates(names: list[str], col: str, *, joint: str | None = None
                    ) -> tuple[list[ColumnName], list[ColumnName]]:
    """Return the best candidates for a record column and the other columns of that quantity.

    Parameters
    ----------
    names : list of str
        Column names still free.
    col : {"t", "x", "v", "u"}
        Record column to fill.
    joint : str, optional
        Joint or servo number already chosen; candidates of another number drop out.

    Returns
    -------
    tuple of (list of ColumnName, list of ColumnName)
        The equally ranked best candidates (one: a clear choice; several: ambiguous; none:
        not found), and the columns of the quantity that were passed over (targets,
        predictions, lower ranks) for the note.
    """
    parsed = [parse_column_name(n) for n in names]
    of_quantity = [p for p in parsed if p.quantity == col]
    if joint is not None and any(p.joint == joint for p in of_quantity):
        of_quantity = [p for p in of_quantity if p.joint == joint]
    allowed = {"measured": 3, "plain": 2}
    if col == "u":
        allowed["target"] = 1  # a commanded torque is the drive's input
    usable = [p for p in of_quantity if p.role in allowed]
    if not usable:
        return [], of_quantity
    score = {p.name: (allowed[p.role], p.exact) for p in usable}
    best = max(score.values())
    top = [p for p in usable if score[p.name] == best]
    return top, [p for p in of_quantity if p not in top]


def matching_names(names: list[str], text: str, repeated: Mapping[str, list[str]]
                   ) -> list[str]:
    """Return the columns a name asked for on the command line may mean.

    Parameters
    ----------
    names : list of str
        Column names of the file.
    text : str
        The name asked for (without surrounding spaces).
    repeated : mapping
        Header names the file repeats -> the column names given to them.

    Returns
    -------
    list of str
        One name: that column. Several: ambiguous. None: no such column.
    """
    if text in repeated:
        return list(repeated[text])
    if text in names:
        return [text]
    low = text.lower()
    same = [n for n in names if n.lower() == low]
    if same:
        return same
    # a base name of numbered columns: 'pos' for 'pos (5)', 'pos (3)', 'pos [4]'
    numbered = [n for n in names if re.fullmatch(
        re.escape(low) + r"\s*[(\[]\s*\d+\s*[)\]]", n.lower())]
    return numbered
