"""The library's front page: the example in ``phid_ros.api``'s docstring runs as written."""

from __future__ import annotations

import doctest
import os
from pathlib import Path

import phid_ros.api

ROOT = Path(__file__).resolve().parents[1]


def test_the_api_docstring_example_runs_and_gives_the_catalogues_inertia() -> None:
    here = Path.cwd()
    os.chdir(ROOT)  # the example reads bags/catalogue, relative as a user in a clone types it
    try:
        failed, attempted = doctest.testmod(phid_ros.api, raise_on_error=False, verbose=False)
    finally:
        os.chdir(here)
    assert attempted >= 6
    assert failed == 0
