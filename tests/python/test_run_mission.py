"""The mission run against `areomap run` on the CLI test's two-site mission."""

import json

import pytest

import areomap
from conftest import cli_error


def without_timings(value):
    """`value` without the wall times it records (they differ between two CLI runs too)."""
    if isinstance(value, dict):
        return {k: without_timings(v) for k, v in value.items() if "seconds" not in k}
    if isinstance(value, list):
        return [without_timings(v) for v in value]
    return value


@pytest.fixture(scope="module")
def mission(cli, tmp_path_factory):
    out = tmp_path_factory.mktemp("tiny") / "mission"
    result = cli("simulate", "--out", out, "--sites", "2", "--navcam-pairs", "1", "--min-leg",
                 "3", "--max-leg", "4", "--quiet")
    assert result.returncode == 0, result.stderr
    return out


def test_summary_matches_the_cli(cli, mission, tmp_path):
    result = cli("--quiet", "run", mission, "--out", tmp_path / "cli", "--no-products")
    assert result.returncode == 0, result.stderr
    expected = json.loads((tmp_path / "cli" / "summary.json").read_text())
    fractions = []
    summary = areomap.run_mission(mission, tmp_path / "py", products=False,
                                  progress=lambda f, stage: fractions.append(f))
    assert without_timings(summary) == without_timings(expected)
    assert summary["command"] == "run"
    assert (tmp_path / "py" / "report.html").exists()
    assert fractions and max(fractions) <= 1.0


def test_cancel_and_errors(cli, mission, tmp_path):
    with pytest.raises(areomap.Error, match="cancelled"):
        areomap.run_mission(mission, tmp_path / "cancelled", progress=lambda f, stage: False)
    assert not (tmp_path / "cancelled" / "summary.json").exists()
    missing = tmp_path / "no_such_mission"
    message = cli_error(cli("run", missing, "--out", tmp_path / "cli"))
    with pytest.raises(areomap.Error) as error:
        areomap.run_mission(missing, tmp_path / "py")
    assert str(error.value) == message
