"""Type stubs of the extension module ``evigrid._evigrid`` (Rust, PyO3).

Users call the plain Python modules of the package; these are the functions they wrap.
"""

from typing import List, Optional, Tuple

__version__: str

# A mass function as the Python layer passes it: (label, frame names, [(set names, mass)]).
_MassArg = Tuple[str, List[str], List[Tuple[List[str], float]]]
# A mass function as returned: (frame names, [(set names, mass)]) in bitmask order.
_MassOut = Tuple[List[str], List[Tuple[List[str], float]]]

class mass:
    """The belief-function calculator (``evigrid.mass`` wraps it)."""

    @staticmethod
    def check(m: _MassArg) -> _MassOut: ...
    @staticmethod
    def combine(rule: str, inputs: List[_MassArg]) -> _MassOut: ...
    @staticmethod
    def discount(
        m: _MassArg,
        alpha: Optional[float] = None,
        contexts: Optional[List[Tuple[List[str], float]]] = None,
        class_rates: Optional[List[Tuple[str, float]]] = None,
        set_rate: Optional[str] = None,
    ) -> _MassOut: ...
    @staticmethod
    def pignistic(m: _MassArg) -> List[Tuple[str, float]]: ...
    @staticmethod
    def transform(m: _MassArg, to: str) -> List[Tuple[List[str], float]]: ...
