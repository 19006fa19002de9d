"""Fixtures of the Python module's tests: the CLI (the reference the bindings are compared to)
and the real sample data beside the checkout (tests skip with a message where either is
missing)."""

import os
import pathlib
import subprocess

import pytest


@pytest.fixture(scope="session")
def cli():
    """Runs `areomap ARGS...` and returns the CompletedProcess (text mode, not checked)."""
    path = os.environ.get("AREOMAP_CLI")
    if not path or not os.path.exists(path):
        pytest.skip("SKIP: the areomap CLI is not built (AREOMAP_BUILD_APPS off)")

    def run(*args, stdin=None):
        return subprocess.run([path, *map(str, args)], input=stdin, capture_output=True,
                              text=True, check=False)

    return run


@pytest.fixture(scope="session")
def shared_data():
    path = pathlib.Path(os.environ.get("AREOMAP_SHARED_DATA_DIR", "../shared/data"))
    if not path.is_dir():
        pytest.skip(f"SKIP: no sample data in {path}")
    return path


@pytest.fixture(scope="session")
def sample_dtm(cli, tmp_path_factory):
    """The CLI's sample DTM GeoTIFF (`areomap sample`): a Mars equirectangular raster."""
    out = tmp_path_factory.mktemp("sample")
    result = cli("--quiet", "sample", "--out", out)
    assert result.returncode == 0, result.stderr
    return out / "sample_dtm.tif"


def cli_error(result):
    """The message of the CLI's `error: ...` line on stderr."""
    assert result.returncode != 0
    lines = [line for line in result.stderr.splitlines() if line.startswith("error: ")]
    assert lines, result.stderr
    return lines[0][len("error: "):]
