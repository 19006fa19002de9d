"""Camera models against `areomap camera project|linearize` on the same files and points."""

import re

import numpy as np
import pytest

import areomap
from conftest import cli_error

NAVCAM = "mer/1N491020376ILFCNY9P0706L0M1.IMG"   # CAHVOR
HAZCAM = "mer/1F490747543EFFCNY9P1214L0M1.IMG"   # CAHVORE
K10 = "k10/black_left.tsai"                        # pinhole with distortion


def points_in_view(model, size, distances):
    """Points [m] on the rays of a grid of pixels, at the given distances."""
    cols, rows = np.meshgrid(np.linspace(0, size[0] - 1, 7), np.linspace(0, size[1] - 1, 5))
    pixels = np.column_stack([cols.ravel(), rows.ravel()])
    origins, directions = model.unproject(pixels)
    return pixels, np.concatenate([origins + d * directions for d in distances])


@pytest.mark.parametrize("name, size", [(NAVCAM, None), (HAZCAM, None), (K10, (1024, 768))])
def test_project_matches_the_cli(cli, shared_data, name, size):
    camera = areomap.read_camera(shared_data / name)
    size = size or camera.image_size
    _, points = points_in_view(camera.model, size, distances=(2.0, 7.5, 40.0))
    behind = 2 * camera.model.center - points[:3]  # mirrored through the centre: behind it
    points = np.concatenate([points, behind])
    text = "".join(f"{p[0]!r} {p[1]!r} {p[2]!r}\n" for p in points)
    result = cli("camera", "project", shared_data / name, stdin=text)
    expected = result.stdout.splitlines()
    pixels = camera.model.project(points)
    assert [f"{u:.6f} {v:.6f}" for u, v in pixels] == expected
    if camera.model.type != "CAHVORE":  # the fish-eye Hazcam sees beyond 90 degrees off axis
        assert np.isnan(pixels[-3:]).all()
        assert result.returncode == 1  # the CLI's status for the points behind the camera


# Tolerances as the library's own tests (tests/map/camera_models_test.cc): CAHVORE's ray is
# found iteratively.
@pytest.mark.parametrize("name, tolerance_px", [(NAVCAM, 1e-6), (HAZCAM, 0.01)])
def test_unproject_then_project_returns_the_pixels(shared_data, name, tolerance_px):
    camera = areomap.read_camera(shared_data / name)
    pixels, points = points_in_view(camera.model, camera.image_size, distances=(3.0,))
    assert np.abs(camera.model.project(points) - pixels).max() < tolerance_px


def test_label_frame_and_site_pose(shared_data):
    camera = areomap.read_camera(shared_data / NAVCAM)
    assert camera.model.type == "CAHVOR" and camera.frame == "ROVER_FRAME"
    assert camera.image_size == (1024, 1024)
    # As `areomap camera show --frame site` prints it (tests/cli camera_site_frame).
    in_site = camera.model.transformed(camera.site_from_frame)
    assert f"{in_site.center[0]:.2f}" == "73.95"
    q = camera.site_from_frame.quaternion
    assert [f"{v:.6g}" for v in q] == ["0.580525", "0.0333603", "-0.128929", "0.803278"]


def test_linearize_matches_the_cli(cli, shared_data):
    camera = areomap.read_camera(shared_data / HAZCAM)
    cahv = camera.model.linearize(camera.image_size, (512, 512))
    assert cahv.type == "CAHV"
    result = cli("camera", "linearize", "--size", "512x512", shared_data / HAZCAM)
    assert result.returncode == 0, result.stderr
    for name in "CAHV":
        line = re.search(rf"^  {name} = (.*)$", result.stdout, re.M).group(1)
        assert " ".join(f"{v:.9g}" for v in cahv.parameters[name]) == line


def test_missing_model_has_the_clis_message(cli, tmp_path):
    notes = tmp_path / "notes.txt"
    notes.write_text("this is a text file, not a raster\n")
    message = cli_error(cli("camera", "show", notes))
    with pytest.raises(areomap.Error) as error:
        areomap.read_camera(notes)
    assert str(error.value) == message
