"""The exceptions evigrid raises: one base class, one subclass per kind of problem."""

from __future__ import annotations

__all__ = ["Error", "InputError", "FileError"]


class Error(Exception):
    """The base class of every exception evigrid raises.

    Its message is one line naming the input (a file, or the argument) and what was wrong with
    it, as the ``evigrid`` command prints it.
    """


class InputError(Error, ValueError):
    """What was passed is wrong: a malformed mass function, an unknown rule, a rate outside
    [0, 1], a value of the wrong type. Fix the input; trying again will not help.

    It is also a ``ValueError``, so code that already catches that keeps working.
    """


class FileError(Error, OSError):
    """A file could not be read or written: missing, unreadable, a full disk. The input may be
    right; the environment failed.

    It is also an ``OSError``, so code that already catches that keeps working.
    """


# Shown as `evigrid.InputError` in tracebacks, where users import them from.
for _class in (Error, InputError, FileError):
    _class.__module__ = "evigrid"
