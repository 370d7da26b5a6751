"""Shared fixtures: the `ebiv` command to compare with, and the shared test data."""

import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]


@pytest.fixture(scope="package")
def ebiv_bin() -> str:
    """The `ebiv` command: `$EBIV_BIN`, else the workspace's release build."""
    path = os.environ.get("EBIV_BIN") or str(REPO / "target" / "release" / "ebiv")
    if not os.path.isfile(path):
        pytest.fail(f"{path} not found: build it (cargo build --release -p ebiv-cli) or set EBIV_BIN")
    return path


@pytest.fixture(scope="package")
def cli(ebiv_bin):
    """Run `ebiv ARGS…`; returns the completed process (output as text)."""

    def run(*args, check=True):
        done = subprocess.run([ebiv_bin, *map(str, args)], capture_output=True, text=True)
        if check and done.returncode != 0:
            raise AssertionError(f"ebiv {' '.join(map(str, args))} failed:\n{done.stderr}")
        return done

    return run


@pytest.fixture(scope="package")
def data():
    """A file of the shared test data (`$EBIV_TEST_DATA`, else ../shared/data beside the
    repository); the test is skipped when it is absent."""
    root = pathlib.Path(os.environ.get("EBIV_TEST_DATA") or REPO.parent / "shared" / "data")

    def find(name: str) -> pathlib.Path:
        path = root / name
        if not path.is_file():
            pytest.skip(f"{path} not found (set EBIV_TEST_DATA)")
        return path

    return find


@pytest.fixture(scope="package")
def simulated(tmp_path_factory, cli):
    """A short simulated recording of the `uniform` example (EVT 3.0) with its truth."""
    d = tmp_path_factory.mktemp("sim")
    cli("simulate", "--example", "uniform", "--duration", "40ms", "--seed", "7",
        "-o", d / "rec.raw", "--truth", d / "truth.nc")
    return d
