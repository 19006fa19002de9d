"""Rasters read by windows, and NumPy arrays in and out of the libraries without copies."""

import numpy as np
import pytest

import areomap
from areomap import _areomap
from conftest import cli_error


def test_window_is_the_same_pixels_with_its_own_georeference(sample_dtm):
    raster = areomap.Raster(sample_dtm)
    full = raster.read()
    assert full.shape == (raster.height, raster.width) and full.dtype == np.float32
    window = (10, 20, 50, 30)
    part, georef = areomap.read_raster(sample_dtm, window=window)
    assert np.array_equal(part, full[20:50, 10:60], equal_nan=True)
    c = raster.geotransform
    g = georef["geotransform"]
    assert g[0] == c[0] + 10 * c[1] + 20 * c[2] and g[3] == c[3] + 10 * c[4] + 20 * c[5]
    assert g[1:3] == c[1:3] and g[4:6] == c[4:6]
    assert "Mars" in georef["crs_wkt"] or "IAU" in georef["crs_wkt"]


def test_stored_type_and_float_agree(shared_data):
    path = shared_data / "craters/hrsc_nanedi_north.png"
    raster = areomap.Raster(path)
    stored = raster.read(as_float=False)
    assert stored.dtype == np.uint8 and raster.geotransform is None
    assert np.array_equal(stored.astype(np.float32), raster.read())


def test_window_outside_and_missing_file_raise(cli, sample_dtm, tmp_path):
    raster = areomap.Raster(sample_dtm)
    with pytest.raises(areomap.Error):
        raster.read(window=(raster.width - 5, 0, 10, 10))
    missing = tmp_path / "missing.tif"
    message = cli_error(cli("info", missing))
    with pytest.raises(areomap.Error) as error:
        areomap.Raster(missing)
    assert str(error.value) == message


def test_contiguous_float32_array_is_read_in_place():
    image = np.zeros((300, 400), dtype=np.float32)
    assert _areomap._image_view_address(image) == image.ctypes.data
    # Row-contiguous views and other cv::Mat types are read in place too.
    rows = image[10:200, 20:300]
    assert _areomap._image_view_address(rows) == rows.ctypes.data
    bytes_ = np.zeros((30, 40), dtype=np.uint8)
    assert _areomap._image_view_address(bytes_) == bytes_.ctypes.data
    # Columns not adjacent, or a dtype cv::Mat lacks: copied to float32.
    strided = image[:, ::2]
    assert _areomap._image_view_address(strided) != strided.ctypes.data
    wide = np.zeros((30, 40), dtype=np.int64)
    assert _areomap._image_view_address(wide) != wide.ctypes.data


def test_arrays_read_are_not_copied_out(sample_dtm):
    array = areomap.Raster(sample_dtm).read()
    assert not array.flags.owndata  # owned by the C++ matrix the reader filled
    assert array.flags.c_contiguous and array.flags.writeable
