"""The examples in the package's docstrings give the numbers they print."""

from __future__ import annotations

import doctest

import pytest

import evigrid
import evigrid.mass


@pytest.mark.parametrize("module", [evigrid, evigrid.mass], ids=lambda m: m.__name__)
def test_docstring_examples_run(module):
    failed, attempted = doctest.testmod(module, verbose=False, report=True)
    assert attempted > 0, f"{module.__name__} has no example"
    assert failed == 0, f"{failed} of {attempted} examples of {module.__name__} failed"
