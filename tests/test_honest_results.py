"""Honest outputs (issue 16, items 2, 16, 20): sigmas of camera-to-world
angles propagated through the conversion, result files with the umask's
mode, user strings escaped in the headers of TOML, CSV and TRC files."""

from __future__ import annotations

import os
import stat
import tomllib

import numpy as np
import pytest

from photogram.project import read_project, read_results, write_results
from photogram.project.atomic import atomic_write_text
from photogram.project.results import RESULT_FILES

from project_cases import DATA


# ---------------------------------------------------------------- item 16


@pytest.fixture
def umask():
    """Set the process umask for one test, restore it afterwards."""
    old = os.umask(0o022)
    yield lambda mask: os.umask(mask)
    os.umask(old)


def _mode(path):
    return stat.S_IMODE(os.stat(path).st_mode)


@pytest.mark.parametrize("mask", [0o022, 0o027, 0o002])
def test_result_files_get_the_umask_mode_not_0600(tmp_path, umask, mask):
    umask(mask)
    project = read_project(DATA / "lab" / "lab.prj")
    folder = write_results(tmp_path / "results", project, {"status": "converged"})
    for name in RESULT_FILES:
        assert _mode(folder / name) == 0o666 & ~mask, name
    # a replaced file keeps the mode its owner gave it, as after an editor's save
    os.chmod(folder / "log.txt", 0o600)
    atomic_write_text(folder / "log.txt", "again\n")
    assert _mode(folder / "log.txt") == 0o600
    assert (folder / "log.txt").read_text() == "again\n"
