"""Shared fixtures of the polarid Python tests."""

import os
from pathlib import Path

import pytest

#: The repository root (python/tests/../..).
REPO_ROOT = Path(__file__).resolve().parents[2]


#: The repository's reference data (oracles, material library, real camera frames).
DATA_DIR = REPO_ROOT / "data"


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """The ``data/`` folder of the repository (see data/README.md)."""
    if not (DATA_DIR / "oracles").is_dir():
        pytest.fail(f"reference data not found at {DATA_DIR} (an incomplete checkout?)")
    return DATA_DIR


def cli_binary() -> Path:
    """The ``polarid`` command-line program: ``$POLARID_CLI`` if set, else the release
    build in the repository's ``target/`` (scripts/test_python.sh builds it)."""
    env = os.environ.get("POLARID_CLI")
    return Path(env) if env else REPO_ROOT / "target" / "release" / "polarid"


@pytest.fixture(scope="session")
def polarid_cli() -> Path:
    exe = cli_binary()
    if not exe.is_file():
        pytest.fail(
            f"the polarid CLI was not found at {exe}: run `cargo build --release -p polarid-cli` "
            "(scripts/test_python.sh does) or set POLARID_CLI"
        )
    return exe


def read_csv(path) -> dict:
    """A CSV written by the CLI as a dict of column lists of strings (``#`` comments
    skipped)."""
    import csv

    lines = [ln for ln in Path(path).read_text().splitlines() if ln and not ln.startswith("#")]
    rows = list(csv.reader(lines))
    header, body = rows[0], rows[1:]
    return {h: [r[i] for r in body] for i, h in enumerate(header)}
