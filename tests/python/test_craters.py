"""Crater detection against `areomap craters` on the real HRSC image: the same records as the
CLI's craters.json, the sun estimate its summary.json reports, errors, cancellation."""

import json
import os
import signal
import sys
import threading
import time
import types

import numpy as np
import pytest

import areomap
from conftest import cli_error

HRSC = "craters/hrsc_nanedi_north.png"


@pytest.fixture(scope="module")
def cli_run(cli, shared_data, tmp_path_factory):
    """`areomap craters HRSC --out DIR` with the sun estimated and the combined detector (the
    CLI's defaults)."""
    out = tmp_path_factory.mktemp("craters")
    result = cli("craters", shared_data / HRSC, "--out", out)
    assert result.returncode == 0, result.stderr
    summary = json.loads((out / "summary.json").read_text())
    craters = json.loads((out / "craters.json").read_text())["craters"]
    return summary, craters


def test_sun_estimate_and_craters_match_the_cli(cli_run, shared_data):
    summary, expected = cli_run
    estimate = areomap.estimate_sun_azimuth(shared_data / HRSC)
    assert estimate == summary["sun_azimuth_estimate"]
    assert estimate["reliable"] and summary["sun_azimuth_source"] == "estimated"
    craters = areomap.detect_craters(shared_data / HRSC, sun_azimuth_deg=estimate["azimuth_deg"])
    assert len(craters) == summary["craters"] > 50
    assert craters == expected  # every field, every bit


def test_an_array_gives_the_same_craters_as_its_file(cli_run, shared_data):
    summary, expected = cli_run
    image = areomap.Raster(shared_data / HRSC).read()  # float32, C-contiguous: no copy
    craters = areomap.detect_craters(image, sun_azimuth_deg=summary["sun_azimuth_deg"])
    assert craters == expected


def test_progress_reaches_one_and_false_cancels(shared_data):
    image = areomap.Raster(shared_data / HRSC).read()[:400, :400]
    seen = []
    areomap.detect_craters(image, progress=lambda f, stage: seen.append((f, stage)))
    assert seen and seen[-1][0] == 1.0 and all(0.0 <= f <= 1.0 for f, _ in seen)
    with pytest.raises(areomap.Error, match="cancelled"):
        areomap.detect_craters(image, progress=lambda f, stage: False)


def test_an_exception_in_progress_stops_the_call_and_propagates(shared_data):
    image = areomap.Raster(shared_data / HRSC).read()[:400, :400]

    def fail(fraction, stage):
        raise ValueError("stop here")

    with pytest.raises(ValueError, match="stop here"):
        areomap.detect_craters(image, progress=fail)


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_ctrl_c_stops_a_long_call(shared_data):
    image = np.tile(areomap.Raster(shared_data / HRSC).read(), (2, 2))
    timer = threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT))
    start = time.monotonic()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            areomap.detect_craters(image, sun_azimuth_deg=270.0)
    finally:
        timer.cancel()
    elapsed = time.monotonic() - start
    print(f"KeyboardInterrupt after {elapsed:.2f} s (SIGINT at 0.5 s)")
    assert elapsed < 20.0


def test_the_gil_is_released_during_detection(shared_data):
    image = np.tile(areomap.Raster(shared_data / HRSC).read(), (2, 2))
    worker = threading.Thread(target=areomap.detect_craters, args=(image,),
                              kwargs={"sun_azimuth_deg": 270.0})
    start = time.monotonic()
    worker.start()
    last, longest_gap = start, 0.0
    while worker.is_alive():  # Python keeps running here while C++ works in the thread
        now = time.monotonic()
        longest_gap, last = max(longest_gap, now - last), now
    elapsed = time.monotonic() - start
    worker.join()
    print(f"detection {elapsed:.2f} s, longest pause of this thread {longest_gap * 1e3:.0f} ms")
    assert elapsed > 0.5 and longest_gap < 0.25 * elapsed


def test_errors_have_the_clis_messages(cli, tmp_path):
    missing = tmp_path / "missing.tif"
    message = cli_error(cli("craters", missing, "--out", tmp_path / "out"))
    with pytest.raises(areomap.Error) as error:
        areomap.detect_craters(missing)
    assert str(error.value) == message
    with pytest.raises(areomap.Error, match="min_diameter_px"):
        areomap.detect_craters(np.zeros((64, 64), np.float32), min_diameter_px=1.0)
    with pytest.raises(TypeError, match="unknown option 'min_diameter'"):
        areomap.detect_craters(np.zeros((64, 64), np.float32), min_diameter=8)
    with pytest.raises(areomap.Error, match="expected a 2-D array"):
        areomap.detect_craters(np.zeros((4, 64, 64), np.float32))


def test_keyword_options_leave_the_callers_options_alone():
    options = areomap.CraterDetectorOptions()
    assert areomap.detect_craters(np.zeros((64, 64), np.float32), options=options,
                                  min_diameter_px=12.0) == []
    assert options.min_diameter_px == 8.0


def test_frames_only_where_pandas_is_installed(monkeypatch):
    records = [{"id": 1, "x_px": 2.5, "y_px": 3.5}]
    catalog = {"georeferenced": False, "craters": records}
    monkeypatch.setitem(sys.modules, "pandas", None)  # as where pandas is not installed
    with pytest.raises(ImportError, match="needs pandas"):
        areomap.craters_frame(catalog)
    made = []
    fake = types.SimpleNamespace(DataFrame=types.SimpleNamespace(
        from_records=lambda rows: made.append(rows) or "frame"))
    monkeypatch.setitem(sys.modules, "pandas", fake)
    assert areomap.craters_frame(catalog) == "frame" and made == [records]
