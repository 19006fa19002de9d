"""Coordinate conversions against `areomap coords` on the same points: identical numbers as
the CLI prints them, and the same error messages."""

import numpy as np
import pytest

import areomap
from conftest import cli_error


def cli_convert(cli, points, *options):
    text = "".join(" ".join(repr(float(v)) for v in p) + "\n" for p in points)
    result = cli("coords", *options, stdin=text)
    assert result.returncode == 0, result.stderr
    return result.stdout.splitlines(), result.stderr


def printed(conversion, values):
    """The rows as the CLI prints them (its decimals per component)."""
    to = conversion.to
    return [" ".join(f"{v:.{to.decimals(i)}f}" for i, v in enumerate(row)) for row in values]


def random_geographic(n, seed):
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-89.9, 89.9, n), rng.uniform(-180, 360, n),
                            rng.uniform(-8000, 20000, n)])


@pytest.mark.parametrize("from_, to, origin", [
    ("planetocentric", "planetographic,west", None),
    ("planetocentric", "mbf", None),
    ("planetocentric", "planetographic,west,360", None),
    ("planetocentric", "site", (-14.5692, 175.4729, -1900.0)),
    ("planetocentric", "IAU_2015:49910", None),
])
def test_convert_matches_the_cli(cli, from_, to, origin):
    points = random_geographic(300, seed=7)
    if origin is not None:  # points within 10 km of the origin for the local frame
        points[:, :2] = np.array(origin[:2]) + (points[:, :2] - [0, 90]) * 1e-3
    options = ["--from", from_, "--to", to]
    if origin is not None:
        options += ["--origin", ",".join(map(repr, origin))]
    expected, _ = cli_convert(cli, points, *options)
    conversion = areomap.Conversion(from_, to, origin=origin)
    assert printed(conversion, conversion(points)) == expected


def test_pixels_take_the_rasters_datum_as_the_cli_does(cli, sample_dtm):
    pixels = np.array([[0.5, 0.5, 0.0], [100.25, 37.75, 10.0], [255.5, 255.5, -3.0]])
    expected, note = cli_convert(cli, pixels, "--from", f"pixel:{sample_dtm}", "--to",
                                 "planetocentric")
    conversion = areomap.Conversion(f"pixel:{sample_dtm}", "planetocentric")
    assert printed(conversion, conversion(pixels)) == expected
    assert conversion.datum_body is not None and conversion.datum_body.a == conversion.datum_body.b
    assert f"a = {conversion.datum_body.a:.0f} m" in note
    # An explicit body keeps the IAU 2000 ellipsoid.
    on_ellipsoid = areomap.Conversion(f"pixel:{sample_dtm}", "planetocentric",
                                      body=areomap.Body.mars2000())
    assert on_ellipsoid.datum_body is None


def test_round_trip_through_mbf():
    points = random_geographic(1000, seed=3)
    back = areomap.convert(areomap.convert(points, "planetocentric", "mbf"), "mbf",
                           "planetocentric,360")
    assert np.allclose(back[:, 0], points[:, 0], atol=1e-9)
    assert np.allclose(np.mod(back[:, 1], 360), np.mod(points[:, 1], 360), atol=1e-9)
    assert np.allclose(back[:, 2], points[:, 2], atol=1e-6)


def test_one_point_in_one_point_out():
    out = areomap.convert([45.0, 10.0, 0.0], "planetocentric", "planetographic,west")
    assert out.shape == (3,)
    assert f"{out[0]:.12f} {out[1]:.12f}" == "45.338231953381 -10.000000000000"


def test_unknown_crs_has_the_clis_message(cli):
    message = cli_error(cli("coords", "--from", "IAU_2015:99999", "--to", "mbf", stdin=""))
    with pytest.raises(areomap.Error) as error:
        areomap.Conversion("IAU_2015:99999", "mbf")
    assert str(error.value) == message


def test_bad_point_raises_naming_it_or_gives_nan(cli):
    result = cli("coords", "--from", "planetocentric", "--to", "mbf", stdin="91 0 0\n")
    line_message = cli_error(result).split(": ", 1)[1]  # after "stdin line 1: "
    points = np.array([[10.0, 20.0, 0.0], [91.0, 0.0, 0.0]])
    with pytest.raises(areomap.Error) as error:
        areomap.convert(points, "planetocentric", "mbf")
    assert str(error.value) == "point 1: " + line_message
    out = areomap.convert(points, "planetocentric", "mbf", errors="nan")
    assert np.isfinite(out[0]).all() and np.isnan(out[1]).all()


def test_points_of_the_wrong_shape_are_refused():
    with pytest.raises(areomap.Error, match=r"expected an array of shape \(N, 3\)"):
        areomap.convert(np.zeros((4, 2)), "planetocentric", "mbf")
