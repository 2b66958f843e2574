"""Shared fixtures: the repository root and the `freeform` command-line binary that the
tests compare the Python package against."""

import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def repo():
    return REPO


@pytest.fixture(scope="session")
def freeform_bin():
    """$FREEFORM_BIN, else a binary cargo already built, else `cargo build --release`."""
    given = os.environ.get("FREEFORM_BIN")
    if given:
        return given
    for profile in ("release", "debug"):
        path = REPO / "target" / profile / "freeform"
        if path.is_file():
            return str(path)
    subprocess.run(
        ["cargo", "build", "--release", "--bin", "freeform"], cwd=REPO, check=True
    )
    return str(REPO / "target" / "release" / "freeform")
