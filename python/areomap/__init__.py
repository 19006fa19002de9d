"""areomap: Mars orbital-ground registration and mapping, from Python.

Thin bindings over the areomap C++ libraries (docs/python.md has a walk-through). Units are
metres and degrees at this interface unless a name says otherwise; raster pixels follow GDAL
(pixel (col, row) covers [col, col+1) x [row, row+1)), camera pixels JPL (first pixel centre at
(0, 0)). Errors of the libraries raise areomap.Error with the message the CLI prints. Long calls
run without the GIL, take an optional progress(fraction, stage) callable (return False to
cancel) and stop on Ctrl-C with KeyboardInterrupt.
"""

import copy
import os

from ._areomap import (  # noqa: F401  (re-exported)
    Body,
    CameraFile,
    CameraModel,
    Conversion,
    CoordinateSystem,
    CraterDetectorOptions,
    Error,
    Raster,
    Rigid3d,
    estimate_sun_azimuth,
    read_camera,
)
from . import _areomap

__all__ = [
    "Body", "CameraFile", "CameraModel", "Conversion", "CoordinateSystem",
    "CraterDetectorOptions", "Error", "Raster", "Rigid3d", "adjust", "convert", "craters_frame",
    "detect_craters", "estimate_sun_azimuth", "read_camera", "read_raster", "register",
    "run_mission",
]


def convert(points, from_, to, body=None, origin=None, errors="raise"):
    """Converts an (N, 3) array of points from system `from_` to system `to`.

    The systems and units of `areomap coords` (see Conversion): e.g. 'planetocentric' (lat, lon
    [deg], h [m]), 'mbf' (X Y Z [m]), 'site' with origin=(lat, lon, h). Returns an (N, 3)
    float64 array (3 values for one point).
    """
    return Conversion(from_, to, body=body, origin=origin)(points, errors=errors)


def read_raster(path, band=1, window=None, as_float=True):
    """Reads a window (col0, row0, width, height) [px] of band `band` of any GDAL raster.

    Returns (array, georeference): the (height, width) array (float32 with NaN for nodata when
    as_float) and a dict with the window's geotransform (None for a plain image) and the CRS's
    WKT (empty when none).
    """
    raster = Raster(path)
    full = (0, 0, raster.width, raster.height)
    window = full if window is None else tuple(window)
    array = raster.read(band=band, window=window, as_float=as_float)
    return array, {"geotransform": raster.window_geotransform(window), "crs_wkt": raster.crs_wkt}


def detect_craters(image, dtm=False, options=None, progress=None, as_frame=False, **option_values):
    """Detects crater rims as ellipses with 1-sigma, as `areomap craters` does.

    image: a path to any GDAL raster (read by tiles; any size), or a 2-D NumPy array (a
    C-contiguous float32 array is read in place, without a copy; NaN = nodata). dtm: the input
    holds heights (rims from curvature crests). options: a CraterDetectorOptions; keyword
    arguments set its fields on a copy, e.g. min_diameter_px=8, sun_azimuth_deg=270,
    method='learned'.
    The sun azimuth is not estimated here: pass one (estimate_sun_azimuth(path) gives it, the
    CLI uses it when 'reliable') or leave the shading checks off.

    Returns the records of `craters.json` (a list of dicts, one per crater: id, x_px, y_px
    (centre, GDAL pixel coordinates), semi-axes [px], angle, 1-sigma values, quality measures;
    for a georeferenced raster also map coordinates, semi-axes [m] and planetocentric lat / east
    lon [deg]). With as_frame=True: a pandas DataFrame, or a geopandas GeoDataFrame (rim centre
    points in the raster's Mars CRS) when geopandas is installed.
    """
    options = CraterDetectorOptions() if options is None else copy.copy(options)
    for name, value in option_values.items():
        if not hasattr(options, name):
            raise TypeError(f"detect_craters: unknown option '{name}'")
        setattr(options, name, value)
    if not hasattr(image, "__array_interface__"):
        image = os.fspath(image)
    catalog = _areomap._detect_craters(image, dtm, options, progress)
    if as_frame:
        return craters_frame(catalog)
    return catalog["craters"]


def craters_frame(catalog):
    """A crater catalogue as a pandas DataFrame, or as a geopandas GeoDataFrame with the rim
    centres as points in the raster's CRS when geopandas is installed and the catalogue is
    georeferenced. `catalog` is what _areomap._detect_craters returns or a list of records."""
    records = catalog["craters"] if isinstance(catalog, dict) else catalog
    try:
        import pandas
    except ImportError as e:
        raise ImportError("craters_frame needs pandas (the records are plain dicts without it)") from e
    frame = pandas.DataFrame.from_records(records)
    if not isinstance(catalog, dict) or not catalog.get("georeferenced"):
        return frame
    try:
        import geopandas
    except ImportError:
        return frame
    return geopandas.GeoDataFrame(
        frame, geometry=geopandas.points_from_xy(frame["map_x"], frame["map_y"]),
        crs=catalog["crs_wkt"])


def register(ortho, orbitals, orbital_dtm=None, prior=None, prior_height_m=None,
             prior_sigma_m=None, site=None, similarity=False, range_m=None,
             max_rotation_deg=None, max_scale_change=None, max_false_match=None, progress=None):
    """Registers a rover orthophoto onto orbital images, as `areomap register` does.

    ortho: orthophoto GeoTIFF (nodata or band 2 = validity mask); orbitals: a path or a list of
    paths of orbital images (any Mars GDAL raster); orbital_dtm: heights for the control points.
    prior: (lat, lon) planetocentric degrees east of the rover (default: the orthophoto's centre
    at prior_height_m [m] above the ellipsoid); prior_sigma_m: its horizontal 1-sigma [m] (the
    search covers 3 sigma); site: MER site index for site-frame control points. range_m,
    max_rotation_deg, max_scale_change, max_false_match: as the CLI's options of those names.
    None keeps the library's default.

    Returns a dict: 'prior', 'matches' (one per orbital image: verdict, reason, shift in px and
    metres east/north with 1-sigma, rotation, scale, correlation, false-match probability),
    'matched', and with a match 'best' (its index), 'edges' (the edge verification),
    'control_points' (ortho and orbital px, lat/lon/h, MBF, covariances) and
    'corrected_geotransform' (the orthophoto's, GDAL order).
    """
    if isinstance(orbitals, (str, os.PathLike)):
        orbitals = [orbitals]
    return _areomap._register(
        os.fspath(ortho), [os.fspath(o) for o in orbitals],
        None if orbital_dtm is None else os.fspath(orbital_dtm),
        None if prior is None else list(prior), prior_height_m, prior_sigma_m, site, similarity,
        range_m, max_rotation_deg, max_scale_change, max_false_match, progress)


def adjust(networks, out_dir, orbital=None, huber=None, alpha=None, rejection_rounds=None,
           rock_tie_variance_factor=None, ellipse_scale=None, progress=None):
    """Bundle-adjusts a rover traverse from network JSON files, as `areomap adjust` does.

    networks: a path or a list of paths (docs/adjustment-format.md), merged in order. Writes
    adjustment.json, report.txt, sites.csv, legs.csv, traverse.gpkg (and traverse_map.png over
    `orbital`) into out_dir, which is created if needed; unlike the CLI it writes there directly
    (no staging folder, no record of earlier outputs). huber [sigmas], alpha, rejection_rounds,
    rock_tie_variance_factor, ellipse_scale: as the CLI's options of those names; None keeps the
    library's default. Returns the key figures (the CLI's summary.json without "command").
    """
    if isinstance(networks, (str, os.PathLike)):
        networks = [networks]
    os.makedirs(out_dir, exist_ok=True)
    return _areomap._adjust(
        [os.fspath(n) for n in networks], os.fspath(out_dir),
        None if orbital is None else os.fspath(orbital), huber, alpha, rejection_rounds,
        rock_tie_variance_factor, ellipse_scale, progress)


def run_mission(mission, out_dir, craters=None, products=None, crater_min_diameter_m=None,
                overwrite=False, progress=None):
    """Runs (or resumes) the whole job on a mission folder, as `areomap run MISSION --out DIR`.

    Stereo, DTM and orthophoto per site, registration onto the orbital image, rock tie points,
    craters, the bundle adjustment and the traverse products, written into out_dir under the
    CLI's output-folder rules (in place, resumable units, a lock; overwrite as --overwrite),
    with summary.json and report.html. craters / products: False skips them (--no-craters,
    --no-products); crater_min_diameter_m as --crater-min-diameter [m]; None keeps the library's
    default. Returns the summary (summary.json's content). Ctrl-C or progress returning False
    stops it; finished site and leg units stay for the next run to resume from.
    """
    return _areomap._run_mission(os.fspath(mission), os.fspath(out_dir), craters, products,
                                 crater_min_diameter_m, overwrite, progress)
