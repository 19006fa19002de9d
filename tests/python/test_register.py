"""Registration against `areomap register` on the CLI test's case: the sample DTM with its
georeference moved 5 m east and 3 m south is put back onto the original."""

import json
import subprocess

import pytest

import areomap
from conftest import cli_error

SHIFT = ["-a_ullr", "-123", "-863135.602675347938", "133", "-863391.602675347938"]
FAR = ["-a_ullr", "9872", "-863132.602675347938", "10128", "-863388.602675347938"]


def translated(sample_dtm, corners, name):
    out = sample_dtm.parent / name
    if not out.exists():
        subprocess.run(["gdal_translate", "-q", *corners, sample_dtm, out], check=True)
    return out


@pytest.fixture(scope="module")
def shifted(sample_dtm):
    return translated(sample_dtm, SHIFT, "shifted.tif")


def test_match_and_control_points_match_the_cli(cli, sample_dtm, shifted, tmp_path):
    out = tmp_path / "out"
    result = cli("--quiet", "register", shifted, sample_dtm, "--out", out,
                 "--max-rotation-deg", "2")
    assert result.returncode == 0, result.stderr
    summary = json.loads((out / "summary.json").read_text())
    stages = []
    registration = areomap.register(shifted, sample_dtm, max_rotation_deg=2,
                                    progress=lambda f, s: stages.append(s))
    assert registration["matched"] and registration["best"] == 0
    for match in summary["matches"]:
        match.pop("cc_surface_png", None)
    assert registration["matches"] == summary["matches"]
    summary["edges"].pop("histograms_png")
    assert registration["edges"] == summary["edges"]
    assert registration["prior"] == summary["prior"]
    assert registration["control_points"] == json.loads((out / "control_points.json").read_text())
    match = registration["matches"][0]
    print("shift E/N [m]:", match["shift_east_m"], match["shift_north_m"])
    assert abs(match["shift_east_m"] + 5.0) < 0.05 and abs(match["shift_north_m"] - 3.0) < 0.05
    assert len(registration["corrected_geotransform"]) == 6 and stages


def test_no_overlap_has_the_clis_message(cli, sample_dtm, tmp_path):
    far = translated(sample_dtm, FAR, "far.tif")
    message = cli_error(cli("register", far, sample_dtm, "--out", tmp_path / "out"))
    assert message.startswith("no orbital image overlaps the search window")
    with pytest.raises(areomap.Error) as error:
        areomap.register(far, [sample_dtm])
    assert str(error.value) == message


def test_bad_option_names_the_field(sample_dtm):
    with pytest.raises(areomap.Error, match="prior_sigma_m"):
        areomap.register(sample_dtm, sample_dtm, prior_sigma_m=-1)
