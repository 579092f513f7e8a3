"""Shared fixtures of the polarid Python tests."""

import os
from pathlib import Path

import pytest

#: The repository root (python/tests/../..).
REPO_ROOT = Path(__file__).resolve().parents[2]


def shared_dir() -> Path:
    """The project's shared reference folder: ``$POLARID_SHARED`` if set, else
    ``../shared`` next to the repository (as on developers' machines and in CI)."""
    env = os.environ.get("POLARID_SHARED")
    return Path(env) if env else REPO_ROOT.parent / "shared"


@pytest.fixture(scope="session")
def shared() -> Path:
    d = shared_dir()
    if not (d / "oracles").is_dir():
        pytest.fail(f"shared reference folder not found at {d} (set POLARID_SHARED)")
    return d
