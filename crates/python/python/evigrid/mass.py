"""Belief functions on small frames: the ``evigrid mass`` calculator as Python functions.

A mass function is a dict in the layout of the calculator's JSON files::

    {"frame": ["a", "b"], "mass": [{"set": ["a"], "m": 0.2}, {"set": ["a", "b"], "m": 0.8}]}

``[]`` is the empty set; a set missing from the list has mass 0. As input, ``"mass"`` may
instead map sets to masses: ``{("a",): 0.2, ("a", "b"): 0.8}``, a set being a tuple (or
frozenset) of element names, or one name alone (``{"a": 0.2, ...}``). A frame has one to eight
elements; masses must be finite, non-negative and sum to 1 (within 1e-9).

Every function returns new values in the file layout (``json.dump`` writes a file the
``evigrid`` command reads), focal sets in increasing bitmask order (element k of the frame is
bit k), zeros left out, every number the one ``evigrid mass ... --json`` prints. A bad input
raises :class:`evigrid.InputError` naming the input (``m``, ``masses[1]`` or the file) and the
problem.

Example (the paper's Table I, Kurdej et al. 2013, as corrected in SPEC §1)::

    >>> from evigrid import mass
    >>> m1 = {"frame": ["a", "b"], "mass": {"a": 0.2, "b": 0.6, ("a", "b"): 0.2}}
    >>> m2 = {"frame": ["a", "b"], "mass": {"a": 0.7, "b": 0.1, ("a", "b"): 0.2}}
    >>> mass.combine([m1, m2], rule="conjunctive")["mass"][0]
    {'set': [], 'm': 0.44}
    >>> mass.pignistic(m1)
    {'a': 0.30000000000000004, 'b': 0.7}
"""

from __future__ import annotations

import json
import numbers
import os
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, Dict, List, Optional, Tuple, Union

from evigrid._errors import FileError, InputError
from evigrid._evigrid import mass as _core

__all__ = [
    "FUNCTIONS",
    "RULES",
    "SET_RATES",
    "check",
    "combine",
    "discount",
    "load",
    "pignistic",
    "transform",
]

RULES = ("conjunctive", "dempster", "disjunctive", "yager", "dubois-prade")
"""The combination rules of SPEC §1, by the names ``combine`` takes."""

FUNCTIONS = ("belief", "plausibility", "commonality", "implicability")
"""The set functions ``transform`` computes."""

SET_RATES = ("min", "max", "mean")
"""How class-rate discounting derives a set's rate from its classes' rates."""

MAX_FILE_BYTES = 16 << 20
"""The largest mass function file ``load`` reads (as the ``evigrid`` command)."""

MassFunction = Dict[str, Any]
"""A mass function in the file layout: ``{"frame": [...], "mass": [{"set": [...], "m": ...}]}``."""

SetLike = Union[str, Iterable[str]]
"""A set of elements: a tuple or frozenset of names, or one name alone."""

# What the extension module takes: the label, the frame's names, (names, mass) pairs.
_Arg = Tuple[str, List[str], List[Tuple[List[str], float]]]


def load(path: Union[str, "os.PathLike[str]"]) -> MassFunction:
    """Reads a mass function file (JSON, the calculator's layout) and checks it.

    Raises :class:`evigrid.FileError` if the file cannot be read and
    :class:`evigrid.InputError` if it is not a valid mass function; both name the file.
    """
    label = os.fspath(path)
    try:
        with open(path, "rb") as file:
            data = file.read(MAX_FILE_BYTES + 1)
    except OSError as error:
        failure = FileError(f"{label}: cannot read: {error.strerror or error}")
        failure.errno = error.errno
        raise failure from None
    if len(data) > MAX_FILE_BYTES:
        raise InputError(f"{label}: larger than {MAX_FILE_BYTES >> 20} MiB; expected a mass function")
    try:
        value = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as error:
        raise InputError(f"{label}: malformed JSON: {error}") from None
    return check(value, label=label)


def check(m: Mapping[str, Any], *, label: str = "m") -> MassFunction:
    """Checks a mass function and returns it in the file layout, focal sets in bitmask order.

    ``label`` names it in the message of the :class:`evigrid.InputError` raised if it is not
    valid.
    """
    return _mass_dict(_core.check(_arg(m, label)))


def combine(masses: Sequence[Mapping[str, Any]], *, rule: str) -> MassFunction:
    """Combines two or more mass functions on the same frame.

    ``rule`` is one of :data:`RULES`: ``conjunctive`` (unnormalised, conflict stays on ∅),
    ``dempster`` (normalised), ``disjunctive``, ``yager`` (conflict to Ω) or ``dubois-prade``
    (conflicting products to the union). Associative rules apply left to right; Yager and
    Dubois–Prade use their n-ary form for more than two inputs. Dempster's rule under total
    conflict (K = 1) raises :class:`evigrid.InputError`.
    """
    if isinstance(masses, Mapping) or not isinstance(masses, Iterable):
        raise InputError(
            f"masses: expected a list of mass functions, not {type(masses).__name__}"
        )
    args = [_arg(m, f"masses[{k}]") for k, m in enumerate(masses)]
    return _mass_dict(_core.combine(_choice("rule", rule, RULES), args))


def discount(
    m: Mapping[str, Any],
    alpha: Optional[float] = None,
    *,
    contexts: Optional[Union[Mapping[Any, float], Iterable[Tuple[SetLike, float]]]] = None,
    class_rates: Optional[Mapping[str, float]] = None,
    set_rate: Optional[str] = None,
) -> MassFunction:
    """Discounts a mass function by exactly one of three modes.

    - ``alpha``: classical discounting; every set keeps 1 − α of its mass, the rest goes to Ω.
    - ``contexts``: contextual discounting (Mercier et al. 2008), a rate per context set, as a
      mapping ``{("h", "r"): 0.1, "a": 0.4}`` or a list of (set, rate) pairs.
    - ``class_rates``: class-rate discounting (SPEC §5 step 3), a rate for every element
      (``{"a": 0.1, "b": 0.5}``); ``set_rate`` (one of :data:`SET_RATES`) says how a set's rate
      follows from its classes' rates. By default, ``max``.

    Rates lie in [0, 1].
    """
    arg = _arg(m, "m")
    given_contexts = None
    if contexts is not None:
        pairs = contexts.items() if isinstance(contexts, Mapping) else contexts
        if isinstance(pairs, (str, bytes)) or not isinstance(pairs, Iterable):
            raise InputError("contexts: expected a mapping of sets to rates")
        given_contexts = []
        for pair in pairs:
            if not isinstance(pair, tuple) or len(pair) != 2:
                raise InputError(f"contexts: {pair!r} is not a (set, rate) pair")
            given_contexts.append((_names(pair[0], "contexts"), _number(pair[1], "contexts")))
    given_rates = None
    if class_rates is not None:
        if not isinstance(class_rates, Mapping):
            raise InputError("class_rates: expected a mapping of elements to rates")
        given_rates = [
            (_name(name, "class_rates"), _number(rate, f"class_rates[{name!r}]"))
            for name, rate in class_rates.items()
        ]
    if alpha is not None:
        alpha = _number(alpha, "alpha")
    if set_rate is not None:
        set_rate = _choice("set_rate", set_rate, SET_RATES)
    return _mass_dict(_core.discount(arg, alpha, given_contexts, given_rates, set_rate))


def pignistic(m: Mapping[str, Any]) -> Dict[str, float]:
    """The pignistic probability of each element, ``{name: betP}`` in frame order.

    ``betP(ω) = Σ_{A∋ω} m(A) / (|A| · (1 − m(∅)))``: a subnormal mass function is normalised
    first, so the values sum to 1; ``m(∅) = 1`` raises :class:`evigrid.InputError`.
    """
    return dict(_core.pignistic(_arg(m, "m")))


def transform(m: Mapping[str, Any], to: str) -> Dict[Tuple[str, ...], float]:
    """A set function on every subset of the frame: ``{(names, ...): value}``.

    ``to`` is one of :data:`FUNCTIONS`: ``belief`` (Σ m(B) over non-empty B ⊆ A),
    ``plausibility`` (Σ m(B) over B meeting A), ``commonality`` (Σ m(B) over B ⊇ A) or
    ``implicability`` (Σ m(B) over B ⊆ A, ∅ included). Keys are tuples of names in frame order,
    ``()`` the empty set, in increasing bitmask order.
    """
    values = _core.transform(_arg(m, "m"), _choice("to", to, FUNCTIONS))
    return {tuple(names): value for names, value in values}


def _mass_dict(result: Tuple[List[str], List[Tuple[List[str], float]]]) -> MassFunction:
    frame, focal = result
    return {"frame": frame, "mass": [{"set": names, "m": m} for names, m in focal]}


def _arg(m: Any, label: str) -> _Arg:
    """A mass function in the extension module's form; every problem of shape is named here."""
    if not isinstance(m, Mapping):
        raise InputError(f"{label}: expected a mass function dict, not {type(m).__name__}")
    keys = set(m)
    if keys != {"frame", "mass"}:
        unknown = sorted(map(repr, keys - {"frame", "mass"}))
        missing = sorted(map(repr, {"frame", "mass"} - keys))
        problem = f"unknown key {', '.join(unknown)}" if unknown else f"no key {', '.join(missing)}"
        raise InputError(f"{label}: {problem}; expected the keys 'frame' and 'mass'")
    frame = m["frame"]
    if isinstance(frame, (str, bytes)) or not isinstance(frame, Iterable):
        raise InputError(f"{label}: frame: expected a list of element names")
    names = [_name(name, f"{label}: frame") for name in frame]
    focal = m["mass"]
    if isinstance(focal, Mapping):
        pairs = [(_names(s, f"{label}: mass"), _number(v, f"{label}: mass")) for s, v in focal.items()]
    elif isinstance(focal, (str, bytes)) or not isinstance(focal, Iterable):
        raise InputError(f"{label}: mass: expected a list of {{'set': [...], 'm': ...}} entries")
    else:
        pairs = [_entry(entry, f"{label}: mass[{k}]") for k, entry in enumerate(focal)]
    return (label, names, pairs)


def _entry(entry: Any, label: str) -> Tuple[List[str], float]:
    if not isinstance(entry, Mapping) or set(entry) != {"set", "m"}:
        raise InputError(f"{label}: expected {{'set': [...], 'm': ...}}, not {entry!r}")
    return _names(entry["set"], label), _number(entry["m"], label)


def _names(value: Any, label: str) -> List[str]:
    if isinstance(value, str):
        return [value]
    if isinstance(value, bytes) or not isinstance(value, Iterable):
        raise InputError(f"{label}: set {value!r} is not a list of element names")
    return [_name(name, label) for name in value]


def _name(value: Any, label: str) -> str:
    if not isinstance(value, str):
        raise InputError(f"{label}: element {value!r} is not a name (str)")
    return value


def _number(value: Any, label: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputError(f"{label}: {value!r} is not a number")
    return float(value)


def _choice(what: str, value: Any, allowed: Tuple[str, ...]) -> str:
    if not isinstance(value, str) or value.replace("_", "-") not in allowed:
        raise InputError(f"{what} {value!r}: expected one of {', '.join(allowed)}")
    return value.replace("_", "-")
