"""Bundle adjustment against `areomap adjust` on the CLI test's network."""

import json
import os
import pathlib

import pytest

import areomap
from conftest import cli_error

NETWORK = pathlib.Path(__file__).resolve().parents[1] / "data" / "adjust" / "network.json"
FILES = ["sites.csv", "legs.csv"]


def without_timings(record):
    """A summary without its *_seconds fields (they differ between two CLI runs too)."""
    return {key: value for key, value in record.items() if not key.endswith("_seconds")}


def test_summary_and_files_match_the_cli(cli, tmp_path):
    result = cli("--quiet", "adjust", NETWORK, "--out", tmp_path / "cli")
    assert result.returncode == 0, result.stderr
    expected = json.loads((tmp_path / "cli" / "summary.json").read_text())
    assert expected.pop("command") == "adjust"
    fractions = []
    summary = areomap.adjust(NETWORK, tmp_path / "py", progress=lambda f, s: fractions.append(f))
    assert without_timings(summary) == without_timings(expected)
    assert summary.keys() == expected.keys()
    assert summary["sites"] == 4 and summary["tie_points"] == 8
    adjustment = [json.loads((tmp_path / d / "adjustment.json").read_text()) for d in ("py", "cli")]
    assert without_timings(adjustment[0]) == without_timings(adjustment[1])
    # report.txt: the same but for its first line's solve and covariance times.
    reports = [(tmp_path / d / "report.txt").read_text().splitlines() for d in ("py", "cli")]
    assert reports[0][1:] == reports[1][1:]
    assert reports[0][0].split("; solve")[0] == reports[1][0].split("; solve")[0]
    for name in FILES:
        assert (tmp_path / "py" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    assert fractions == sorted(fractions)


def test_bad_input_has_the_clis_message(cli, tmp_path):
    bad = tmp_path / "not_json.json"
    bad.write_text('{"sites": [\n')
    message = cli_error(cli("adjust", bad, "--out", tmp_path / "cli"))
    with pytest.raises(areomap.Error) as error:
        areomap.adjust(bad, tmp_path / "py")
    assert str(error.value) == message
    assert os.listdir(tmp_path / "py") == []  # nothing written before the input is read
