"""Packaging metadata in the form current setuptools reads without a warning.

``make demo``'s ``pip install`` builds in an isolated environment with the newest
setuptools the index has (80+); a ``project.license`` table there prints a long
"``project.license`` as a TOML table is deprecated" block a new user takes for an error.
Checked by hand with ``pip wheel . --no-deps``: no warning, ``License-Expression: MIT``.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

PYPROJECT = Path(__file__).resolve().parents[1] / "pyproject.toml"


def test_license_is_an_spdx_string_with_a_setuptools_that_reads_it():
    data = tomllib.loads(PYPROJECT.read_text())
    assert data["project"]["license"] == "MIT"  # an SPDX expression, not a table
    # SPDX strings need setuptools 77 (an older one would refuse the string)
    (req,) = [r for r in data["build-system"]["requires"] if r.startswith("setuptools")]
    found = re.fullmatch(r"setuptools>=(\d+)(\.\d+)*", req)
    assert found and int(found.group(1)) >= 77, req
    classifiers = data["project"].get("classifiers", [])
    assert not [c for c in classifiers if c.startswith("License ::")]  # refused beside SPDX
