"""evigrid: evidential occupancy grids fused with OpenStreetMap maps, from Python.

The package is numpy-first and thin: the numbers come from the Rust library crates, built into
the extension module ``evigrid._evigrid``; what is here turns them into Python values.

- ``evigrid.mass``: the belief-function calculator (combination rules, discounting, pignistic
  probability, belief/plausibility/commonality/implicability), the same numbers as the
  ``evigrid mass`` command.
- ``evigrid.Error``: the base class of every exception raised, with ``InputError`` (bad input, a
  ``ValueError``) and ``FileError`` (a file could not be read or written, an ``OSError``).

Example::

    >>> import evigrid
    >>> m1 = {"frame": ["a", "b"], "mass": {("a",): 0.2, ("b",): 0.6, ("a", "b"): 0.2}}
    >>> m2 = {"frame": ["a", "b"], "mass": {("a",): 0.7, ("b",): 0.1, ("a", "b"): 0.2}}
    >>> evigrid.mass.pignistic(evigrid.mass.combine([m1, m2], rule="dempster"))["a"]
    0.6071428571428571
"""

from __future__ import annotations

from evigrid import mass
from evigrid._errors import Error, FileError, InputError
from evigrid._evigrid import __version__

__all__ = ["Error", "FileError", "InputError", "__version__", "mass"]
