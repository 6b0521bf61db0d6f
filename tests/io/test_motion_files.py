"""The motion-file writers against independent readers: C3D written with ezc3d and read back
with the ``c3d`` package; .mot, .trc and the XMALab CSV parsed here with plain text
handling; the frame rate checked, stored and read from videos and DICOM headers."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fluorogui.io.errors import InputError
from fluorogui.io.motion_files import (
    check_fps,
    frame_rate_source,
    frame_times,
    store_frame_rate,
    stored_frame_rate,
    write_c3d,
    write_mot,
    write_trc,
    write_xromm_csv,
)


def read_c3d(path):
    """Labels, rate, units, points (frames × markers × 3), residuals and the FLUOROGUI
    parameters of a C3D, through the ``c3d`` package (not the library that wrote it)."""
    import warnings

    import c3d

    with open(path, "rb") as handle, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "no analog data": there is none
        reader = c3d.Reader(handle)
        labels = [label.strip() for label in reader.point_labels]
        frames = [points.copy() for _, points, _ in reader.read_frames()]
        info = {"rate": reader.point_rate, "units": reader.get("POINT:UNITS").string_value.strip(),
                "frames": reader.get("FLUOROGUI:FRAMES").float_array,
                "times": reader.get("FLUOROGUI:TIMES").float_array,
                "descriptions": [d.strip() for d in reader.get("POINT:DESCRIPTIONS").string_array]}
    data = np.array(frames)
    return labels, data[:, :, :3], data[:, :, 3], info


def test_c3d_markers_read_back_by_another_library(tmp_path):
    rng = np.random.default_rng(4)
    points = rng.uniform(-400, 400, size=(5, 3, 3))  # frames × markers × xyz, mm
    valid = np.ones((5, 3), bool)
    valid[1, 2] = valid[4, 0] = False
    points[3, 1] = np.nan  # a missing pose is invalid whatever ``valid`` says
    path = tmp_path / "m.c3d"
    write_c3d(path, ["a_origin", "a_x", "b_origin"], points, valid, fps=29.97, frames=[10, 11, 12, 13, 14],
              descriptions=["one", "two", "three"])
    labels, read, residual, info = read_c3d(path)
    assert labels == ["a_origin", "a_x", "b_origin"]
    assert math.isclose(info["rate"], 29.97, rel_tol=1e-6) and info["units"] == "mm"
    assert info["descriptions"] == ["one", "two", "three"]
    np.testing.assert_array_equal(info["frames"], [10, 11, 12, 13, 14])
    np.testing.assert_allclose(info["times"], np.arange(10, 15) / 29.97, rtol=1e-6)
    good = valid & np.all(np.isfinite(points), axis=2)
    assert np.array_equal(residual < 0, ~good) and np.all(residual[good] == 0)
    assert np.all(read[~good] == 0)  # invalid markers: zero coordinates, residual -1
    # float32 storage: measured 1.5e-5 mm at coordinates up to 400 mm
    assert np.abs(read[good] - points[good]).max() < 5e-5


def test_c3d_replaces_a_file_atomically_and_leaves_no_temp(tmp_path):
    path = tmp_path / "m.c3d"
    path.write_bytes(b"old")
    write_c3d(path, ["p"], np.zeros((2, 1, 3)), np.ones((2, 1), bool), fps=10.0, frames=[0, 1])
    assert path.read_bytes()[:1] != b"o" and sorted(p.name for p in tmp_path.iterdir()) == ["m.c3d"]
    with pytest.raises(InputError, match="m.c3d"):  # a folder in the way: the error names the file
        write_c3d(tmp_path / "dir" / "m.c3d", ["p"], np.zeros((2, 1, 3)), np.ones((2, 1), bool), fps=10.0, frames=[0,
                                                                                                                   1])


def parse_mot(path):
    lines = path.read_text().splitlines()
    end = lines.index("endheader")
    header = lines[:end]
    columns = lines[end + 1].split("\t")
    table = np.array([[float(v) for v in line.split("\t")] for line in lines[end + 2:]])
    return header, columns, table


def test_mot_is_an_opensim_storage_table(tmp_path):
    table = np.array([[10.0, 1.0, -2.0, 0.001, 0.002, 0.030], [np.nan] * 6])
    path = tmp_path / "k.mot"
    write_mot(path, "knee", ["a", "b", "c", "d", "e", "f"], np.array([0.0, 0.04]), table=table,
              notes=["units: translations in meters", "a=b is not a setting"])
    header, columns, read = parse_mot(path)
    assert header[0] == "knee" and "inDegrees=yes" in header and "nRows=2" in header and "nColumns=7" in header
    settings = [line for line in header[1:] if "=" in line]
    assert settings == ["version=1", "nRows=2", "nColumns=7", "inDegrees=yes"]  # notes carry no "="
    assert "units: translations in meters" in header
    assert columns == ["time", "a", "b", "c", "d", "e", "f"]
    np.testing.assert_array_equal(read[:, 0], [0.0, 0.04])
    np.testing.assert_array_equal(read[0, 1:], table[0])
    assert np.all(np.isnan(read[1, 1:]))


def test_trc_has_opensims_header_and_empty_missing_markers(tmp_path):
    points = np.arange(2 * 2 * 3, dtype=float).reshape(2, 2, 3) + 0.5
    valid = np.array([[True, True], [True, False]])
    path = tmp_path / "m.trc"
    write_trc(path, ["p", "q"], [7, 9], np.array([0.7, 0.9]), points=points, valid=valid, fps=10.0)
    lines = path.read_text().split("\n")
    assert lines[0].split("\t") == ["PathFileType", "4", "(X/Y/Z)", "m.trc"]
    keys, values = lines[1].split("\t"), lines[2].split("\t")
    info = dict(zip(keys, values))
    assert info["DataRate"] == "10" and info["NumFrames"] == "2" and info["NumMarkers"] == "2"
    assert info["Units"] == "mm"
    assert lines[3].split("\t") == ["Frame#", "Time", "p", "", "", "q", "", ""]
    assert lines[4].split("\t") == ["", "", "X1", "Y1", "Z1", "X2", "Y2", "Z2"]
    assert lines[5] == ""
    first, second = (line.split("\t") for line in lines[6:8])
    assert first[:2] == ["7", "0.7"] and [float(v) for v in first[2:]] == list(points[0].ravel())
    assert [float(v) for v in second[2:5]] == list(points[1, 0]) and second[5:] == ["", "", ""]


def test_xromm_csv_is_column_major_16_per_body(tmp_path):
    a = np.arange(16, dtype=float).reshape(4, 4)
    path = tmp_path / "x.csv"
    write_xromm_csv(path, ["femoral", "tibial"], [[a, None], [None, a.T]])
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    assert len(header) == 32 and header[:4] == ["femoral_m11", "femoral_m21", "femoral_m31", "femoral_m41"]
    assert header[12:16] == ["femoral_m14", "femoral_m24", "femoral_m34", "femoral_m44"]
    assert header[16] == "tibial_m11"
    rows = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    np.testing.assert_array_equal(rows[0, :16].reshape(4, 4, order="F"), a)
    np.testing.assert_array_equal(rows[1, 16:].reshape(4, 4, order="F"), a.T)
    assert np.all(np.isnan(rows[0, 16:])) and np.all(np.isnan(rows[1, :16]))


@pytest.mark.parametrize("bad", [0, -5, float("nan"), float("inf"), "fast", 2e6, None])
def test_a_frame_rate_must_be_a_positive_number(bad):
    with pytest.raises(InputError, match="--fps"):
        check_fps(bad, "--fps")


def test_frame_rate_kept_in_settings():
    settings = {}
    assert stored_frame_rate(settings) is None and frame_rate_source(settings) == ""
    store_frame_rate(settings, 7.5, "user")
    assert stored_frame_rate(settings) == 7.5 and frame_rate_source(settings) == "user"
    np.testing.assert_allclose(frame_times([0, 3, 15], 7.5), [0.0, 0.4, 2.0])
    settings["time"]["fps"] = "garbage"  # a hand-edited project: no frame rate, not a crash
    assert stored_frame_rate(settings) is None
    store_frame_rate(settings, None)
    assert "time" not in settings


def test_frame_rate_read_from_dicom_and_video(tmp_path):
    import cv2

    from fluorogui.io.importer import source_frame_rate
    from tests.io.test_image_formats import make_dicom, twelve_bit_frames

    make_dicom(tmp_path / "run.dcm", twelve_bit_frames())
    assert source_frame_rate(tmp_path / "run.dcm") is None  # says nothing
    import pydicom

    ds = pydicom.dcmread(tmp_path / "run.dcm")
    ds.FrameTime = "40"  # ms per frame
    ds.CineRate = "30"
    ds.save_as(tmp_path / "timed.dcm")
    assert source_frame_rate(f"{tmp_path / 'timed.dcm'}@1") == (25.0, "timed.dcm (DICOM FrameTime)")
    del ds.FrameTime
    ds.save_as(tmp_path / "cine.dcm")
    assert source_frame_rate(tmp_path / "cine.dcm") == (30.0, "cine.dcm (DICOM CineRate)")
    writer = cv2.VideoWriter(str(tmp_path / "v.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 12.5, (32, 24), isColor=False)
    for level in (0, 100, 200):
        writer.write(np.full((24, 32), level, np.uint8))
    writer.release()
    rate, where = source_frame_rate(tmp_path / "v.avi@0")
    assert rate == pytest.approx(12.5) and where == "v.avi (video)"
    assert source_frame_rate(tmp_path / "absent.avi") is None
