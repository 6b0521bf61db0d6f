"""Calibration readers: MayaCam 1.0 / 2.0, JointTrack, our JSON, and their error messages."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from fluorogui.core.projection.geometry import DEFAULT_PITCH_MM, View
from fluorogui.core.projection.pose import rotation_matrix
from fluorogui.io.calibration import (
    check_image_size,
    jointtrack_matrix,
    jointtrack_to_pose,
    load_jointtrack_poses,
    load_view,
    save_view_json,
)
from fluorogui.io.errors import InputError

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"

MAYACAM2 = """image size
1024,1024

camera matrix
4576.77643523,0,395.255884504
0,4601.74685987,588.40125626
0,0,1

rotation
0.572791364402,0.594630409096,-0.564202737891
-0.589633497625,-0.179252057748,-0.787528436485
-0.569422858116,0.783762321352,0.24793997718

translation
36.2384826278
-134.635431317
1345.59296415
"""


def write(tmp_path, text, name="cam.txt"):
    path = tmp_path / name
    path.write_text(text)
    return path


def data_file(*parts) -> Path:
    path = DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"shared data not available: {path}")
    return path


def assert_error(path, fragment, **kwargs):
    with pytest.raises(InputError) as info:
        load_view(path, **kwargs)
    message = str(info.value)
    assert message.startswith(f"{path}: ")
    assert fragment in message
    assert "\n" not in message
    return message


# -- MayaCam 2.0 --------------------------------------------------------------------------------
def test_mayacam2_matches_opencv_projection(tmp_path):
    view = load_view(write(tmp_path, MAYACAM2), name="cam1")
    K = np.array([[4576.77643523, 0, 395.255884504], [0, 4601.74685987, 588.40125626], [0, 0, 1]])
    R = np.array(
        [
            [0.572791364402, 0.594630409096, -0.564202737891],
            [-0.589633497625, -0.179252057748, -0.787528436485],
            [-0.569422858116, 0.783762321352, 0.24793997718],
        ]
    )
    t = np.array([36.2384826278, -134.635431317, 1345.59296415])
    points = np.random.default_rng(0).uniform(-60, 60, size=(20, 3))
    cam = points @ R.T + t
    expected = (cam @ K.T)[:, :2] / cam[:, 2:]
    np.testing.assert_allclose(view.project(points), expected, atol=1e-5)
    assert view.name == "cam1"
    assert view.image_size == (1024, 1024)
    assert view.pitch[0] == pytest.approx(DEFAULT_PITCH_MM)
    assert view.extra["pitch_assumed"]


def test_mayacam2_real_files_load():
    for name in ("cam1_mayacam2.txt", "cam2_mayacam2.txt"):
        view = load_view(data_file("biplane-tka", "calibration", name))
        assert view.image_size == (1024, 1024)
        # the knee sits near the world origin: it projects inside the image, in front of the source
        u, v = view.project(np.zeros((1, 3)))[0]
        assert 0 < u < 1024 and 0 < v < 1024


def test_mayacam2_crlf_and_single_row_translation(tmp_path):
    text = MAYACAM2.replace("36.2384826278\n-134.635431317\n1345.59296415",
                            "36.2384826278,-134.635431317,1345.59296415")
    a = load_view(write(tmp_path, MAYACAM2.replace("\n", "\r\n"), "a.txt"))
    b = load_view(write(tmp_path, text, "b.txt"))
    np.testing.assert_allclose(a.source, b.source)


def test_mayacam2_missing_section(tmp_path):
    text = MAYACAM2.split("translation")[0]
    assert_error(write(tmp_path, text), "missing the section 'translation'")


def test_mayacam2_non_numeric(tmp_path):
    assert_error(write(tmp_path, MAYACAM2.replace("0.572791364402", "0.57x")), "non-numeric value '0.57x'")


def test_mayacam2_nan(tmp_path):
    assert_error(write(tmp_path, MAYACAM2.replace("-134.635431317", "nan")),
                 "NaN or infinite value in section 'translation'")


def test_mayacam2_wrong_row_count(tmp_path):
    text = MAYACAM2.replace("0,0,1\n", "")
    assert_error(write(tmp_path, text), "section 'camera matrix' needs 3 rows of 3 numbers")


def test_mayacam2_singular_camera_matrix(tmp_path):
    text = MAYACAM2.replace("4576.77643523,0,395.255884504", "0,0,0")
    assert_error(write(tmp_path, text), "camera matrix is singular")


def test_mayacam2_not_a_rotation(tmp_path):
    text = MAYACAM2.replace("0.572791364402,0.594630409096", "1.572791364402,0.594630409096")
    assert_error(write(tmp_path, text), "rotation matrix is not a proper rotation")


# -- MayaCam 1.0 --------------------------------------------------------------------------------
def mayacam1_text(view: View) -> str:
    """A MayaCam 1.0 file of ``view`` written with Autoscoper's angle extraction (to_xyzypr)."""
    A = np.column_stack([view.e_u, -view.e_v, -view.normal])  # camera-to-world, OpenGL axes
    yaw = math.degrees(math.atan2(A[1, 0], A[0, 0]))
    pitch = math.degrees(math.atan2(-A[2, 0], math.hypot(A[2, 1], A[2, 2])))
    roll = math.degrees(math.atan2(A[2, 1], A[2, 2]))
    w, h = view.image_size
    f = view.focal_px[0]
    u0 = view.principal_point[0] + 1
    v0 = (h - 1) - view.principal_point[1] + 1
    scale = 0.1
    x, y, z = (float(c) for c in view.source)
    f, u0, v0 = float(f), float(u0), float(v0)
    return (
        f"{x!r},{y!r},{z!r}\n{roll!r},{pitch!r},{yaw!r}\n"
        f"{scale * (w / 2 - u0)!r},{scale * (h / 2 - v0)!r},{-scale * f!r}\n"
        f"{u0!r},{v0!r},{-f!r}\n{scale},{w},{h}\n"
    )


def test_mayacam1_agrees_with_mayacam2(tmp_path):
    cam2 = load_view(write(tmp_path, MAYACAM2.replace("4601.74685987", "4576.77643523"), "m2.txt"))
    cam1 = load_view(write(tmp_path, mayacam1_text(cam2), "m1.txt"))
    points = np.random.default_rng(1).uniform(-60, 60, size=(20, 3))
    np.testing.assert_allclose(cam1.project(points), cam2.project(points), atol=1e-6)
    assert cam1.extra["source_format"] == "MayaCam 1.0"


def test_mayacam1_autoscoper_docs_example(tmp_path):
    text = "-737.5,-514.9,94.3\n89.7,-2.0,-55.2\n3.9,4.1,-632.5\n840.2,839.2,-6325.8\n0.1,1760,1760\n"
    view = load_view(write(tmp_path, text))
    assert view.image_size == (1760, 1760)
    assert view.focal_px[0] == pytest.approx(6325.8)
    assert view.principal_point == pytest.approx((839.2, 1759 - 838.2))
    # a point on the optical axis lands on the principal point
    on_axis = view.source + 500 * view.normal
    np.testing.assert_allclose(view.project(on_axis[None])[0], view.principal_point, atol=1e-9)


def test_mayacam1_zero_size_means_1024(tmp_path):
    view = load_view(write(tmp_path, "0,0,1000\n0,0,0\n0,0,-100\n512,512,-5000\n0,0,0\n"))
    assert view.image_size == (1024, 1024)


def test_mayacam1_non_numeric(tmp_path):
    assert_error(write(tmp_path, "0,0,1000\n0,0,0\n0,0,-100\n512,abc,-5000\n0,0,0\n"),
                 "non-numeric value 'abc' in line 4")
    assert_error(write(tmp_path, "0,0,1000\n0,0,0\n0,0,-100\n512,512,inf\n0,0,0\n"), "NaN or infinite value in line 4")
    assert_error(write(tmp_path, "0,0,1000\n0,0,0\n0,0,-100\n512,512,0\n0,0,0\n"), "camera matrix is singular")


# -- JointTrack ------------------------------------------------------------------------------------
def test_jointtrack_calibration(tmp_path):
    path = write(tmp_path, "JT_INTCALIB\n1198\n3.73\n-7.46\n0.373\n")
    view = load_view(path, image_size=(1024, 768))
    assert view.principal_point == pytest.approx((512 + 10, 384 + 20))
    X = np.array([[18.5, 19.7, -1027.7]])
    u = view.principal_point[0] + (1198 / 0.373) * X[0, 0] / -X[0, 2]
    v = view.principal_point[1] - (1198 / 0.373) * X[0, 1] / -X[0, 2]
    np.testing.assert_allclose(view.project(X)[0], [u, v])


def test_jointtrack_real_files():
    view = load_view(data_file("single-plane-tka", "calibration.txt"))
    poses = load_jointtrack_poses(data_file("single-plane-tka", "fem.jts"))
    assert view.distance == 1198 and view.pitch == (0.373, 0.373) and view.image_size == (1024, 1024)
    assert poses.shape == (3, 6)
    assert poses[0, 0] == pytest.approx(18.52191) and poses[0, 5] == pytest.approx(-0.2587041)
    uv = view.project(poses[:, :3])
    assert np.all((uv > 0) & (uv < 1024))


def test_jointtrack_pose_conversion_gives_same_rotation():
    rng = np.random.default_rng(2)
    for _ in range(50):
        row = np.concatenate([rng.uniform(-50, 50, 3), rng.uniform(-170, 170, 3)])
        row[4] = rng.uniform(-85, 85)  # keep away from the gimbal lock of either convention
        pose = jointtrack_to_pose(row)
        np.testing.assert_allclose(rotation_matrix(*pose[3:]), jointtrack_matrix(row), atol=1e-10)
        np.testing.assert_allclose(pose[:3], row[:3])


def test_jointtrack_matrix_is_z_then_x_then_y():
    row = [0, 0, 0, 30.0, 0, 0]
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    np.testing.assert_allclose(jointtrack_matrix(row), [[c, -s, 0], [s, c, 0], [0, 0, 1]], atol=1e-12)


def test_jointtrack_errors(tmp_path):
    assert_error(write(tmp_path, "JT_INTCALIB\n1198\n0\n"), "JT_INTCALIB needs 4 numbers")
    assert_error(write(tmp_path, "JT_INTCALIB\n1198\n0\nzero\n0.3\n"), "non-numeric value 'zero'")
    assert_error(write(tmp_path, "JT_INTCALIB\n1198\n0\n0\n-0.3\n"), "must be positive")
    bad = write(tmp_path, "JT_EULER_312\nx,y,z,a,b,c\n1,2,3,4,5\n", "p.jts")
    with pytest.raises(InputError, match="line 3 has 5 numbers, expected 6"):
        load_jointtrack_poses(bad)
    with pytest.raises(InputError, match="first line must be JT_EULER_312"):
        load_jointtrack_poses(write(tmp_path, MAYACAM2, "q.jts"))


# -- JSON --------------------------------------------------------------------------------------------
def test_json_round_trip(tmp_path):
    view = load_view(write(tmp_path, MAYACAM2), name="cam1")
    save_view_json(view, tmp_path / "cam1.json")
    again = load_view(tmp_path / "cam1.json")
    assert again.to_dict() == view.to_dict()
    assert not list(tmp_path.glob("*.tmp"))


def test_json_newer_version_refused(tmp_path):
    path = write(tmp_path, '{"format": "fluorogui-calibration", "version": 7, "view": {}}', "c.json")
    assert_error(path, "written by a newer fluorogui (calibration version 7 > 1)")


def test_json_errors(tmp_path):
    assert_error(write(tmp_path, '{"format": "fluorogui-calibration", "vers', "a.json"), "truncated or not valid JSON")
    assert_error(write(tmp_path, '{"format": "something"}', "b.json"), "not a fluorogui calibration")
    text = '{"format": "fluorogui-calibration", "version": 1, "view": {"name": "x"}}'
    assert_error(write(tmp_path, text, "c.json"), "missing the field")


# -- general errors ------------------------------------------------------------------------------------
def test_missing_file(tmp_path):
    assert_error(tmp_path / "nope.txt", "file not found")


def test_unknown_format(tmp_path):
    assert_error(write(tmp_path, "hello\nworld\n"), "unknown calibration format")
    assert_error(write(tmp_path, ""), "calibration file is empty")
    binary = tmp_path / "b.txt"
    binary.write_bytes(b"\x00\x01\x02")
    assert_error(binary, "binary file")


def test_check_image_size(tmp_path):
    view = load_view(write(tmp_path, MAYACAM2), name="cam1")
    check_image_size(view, (1024, 1024), "img.tif")
    with pytest.raises(InputError) as info:
        check_image_size(view, (512, 640), "img.tif")
    assert str(info.value) == \
        f"img.tif: image is 640x512 px but the calibration 'cam1' ({tmp_path / 'cam.txt'}) is for 1024x1024 px"


# -- writing: round trips -------------------------------------------------------------------------
def _assert_same_view(a: View, b: View, rtol=1e-9):
    for key in ("source", "normal", "e_u", "e_v"):
        np.testing.assert_allclose(getattr(a, key), getattr(b, key), rtol=rtol, atol=rtol * 1e-3)
    assert a.distance == pytest.approx(b.distance, rel=rtol)
    np.testing.assert_allclose(a.pitch, b.pitch, rtol=rtol)
    np.testing.assert_allclose(a.principal_point, b.principal_point, rtol=rtol)
    assert a.image_size == b.image_size


def _numbers_of(text: str) -> np.ndarray:
    import re

    return np.array([float(x) for x in re.findall(r"[-+]?\d+\.?\d*(?:[eE][-+]?\d+)?", text)])


@pytest.mark.parametrize("fmt", ["json", "mayacam2", "mayacam1"])
def test_view_file_view_round_trip(tmp_path, fmt):
    from fluorogui.io.calibration import save_view

    view = View.looking_at((812.3, -95.1, 240.7), (3.2, 1.1, -4.0), (0.1, 0.2, 1.0), 1187.654321,
                           image_size=(1024, 768), pitch=DEFAULT_PITCH_MM, name="cam")
    view = View(view.source, view.normal, view.e_u, view.e_v, view.distance, view.pitch, (530.25, 371.875),
                view.image_size, "cam")
    save_view(view, tmp_path / "v.txt", fmt)
    back = load_view(tmp_path / "v.txt", name="cam")
    _assert_same_view(view, back)


@pytest.mark.parametrize("fmt", ["mayacam2", "mayacam1"])
def test_file_view_file_round_trip_real(tmp_path, fmt):
    from fluorogui.io.calibration import save_view

    original = data_file("biplane-tka", "calibration", "cam2_mayacam2.txt")
    view = load_view(original)
    if fmt == "mayacam1":  # one focal length only: refused for this camera (fx != fy), fine when equal
        with pytest.raises(InputError, match="one focal length"):
            save_view(view, tmp_path / "refused.txt", fmt)
        assert not (tmp_path / "refused.txt").exists()
        view = View(view.source, view.normal, view.e_u, view.e_v, view.distance, (view.pitch[0],) * 2,
                    view.principal_point, view.image_size)
    save_view(view, tmp_path / "a.txt", fmt)
    save_view(load_view(tmp_path / "a.txt"), tmp_path / "b.txt", fmt)
    first, second = (_numbers_of((tmp_path / n).read_text()) for n in ("a.txt", "b.txt"))
    np.testing.assert_allclose(second, first, rtol=1e-9, atol=1e-9)
    if fmt == "mayacam2":  # the exported numbers are the file's own
        np.testing.assert_allclose(first, _numbers_of(original.read_text()), rtol=1e-9, atol=1e-9)


def test_mayacam2_width_first(tmp_path):
    from fluorogui.io.calibration import save_view_mayacam2

    view = load_view(write(tmp_path, MAYACAM2.replace("1024,1024", "1280,720")))
    assert view.image_size == (1280, 720)
    save_view_mayacam2(view, tmp_path / "out.txt")
    assert (tmp_path / "out.txt").read_text().splitlines()[1] == "1280,720"


def test_jointtrack_round_trip_and_refusal(tmp_path):
    from fluorogui.io.calibration import save_view_jointtrack

    path = write(tmp_path, "JT_INTCALIB\n1198\n3.73\n-7.46\n0.373\n")
    view = load_view(path)
    save_view_jointtrack(view, tmp_path / "jt.txt")
    np.testing.assert_allclose(_numbers_of((tmp_path / "jt.txt").read_text()), [1198, 3.73, -7.46, 0.373], rtol=1e-12)
    _assert_same_view(view, load_view(tmp_path / "jt.txt"))
    moved = View.looking_at((0, 0, 1000), (0, 0, 0), (0, 1, 0), 1198, image_size=(1024, 1024), pitch=0.373)
    with pytest.raises(InputError, match="own camera frame"):
        save_view_jointtrack(moved, tmp_path / "no.txt")
    assert not (tmp_path / "no.txt").exists()


def test_mayacam2_undistortion_block_read_written_and_kept_in_json(tmp_path):
    from fluorogui.io.calibration import save_view_mayacam2

    coefficients = [-0.12, 0.034, 0.0011, -0.0007, 0.002, 0.0, 0.0, 0.0]
    text = MAYACAM2 + "\nundistortion\n" + ",".join(map(str, coefficients)) + "\n"
    view = load_view(write(tmp_path, text))
    assert view.extra["distortion"]["model"] == "opencv"
    assert view.extra["distortion"]["coefficients"] == coefficients
    save_view_mayacam2(view, tmp_path / "again.txt")
    assert load_view(tmp_path / "again.txt").extra["distortion"]["coefficients"] == coefficients
    save_view_json(view, tmp_path / "v.json")
    assert load_view(tmp_path / "v.json").extra["distortion"] == view.extra["distortion"]
    assert_error(write(tmp_path, MAYACAM2 + "\nundistortion\n0.1,0.2,0.3\n", "bad.txt"), "section 'undistortion' has 3")


# -- what a fluoroscope can plausibly be: refused when read, naming the file and the field ------
@pytest.mark.parametrize("old, new, words", [
    ("4576.77643523,0,395", "1e-12,0,395", "section 'camera matrix' (fx, fy): focal length fx = 1e-12 px gives a "
                                           "180° field of view across 1024 px; a fluoroscope's is 0.1° to 120°"),
    ("4576.77643523,0,395", "1e9,0,395", "section 'camera matrix' (fx, fy): focal length fx = 1e+09 px gives a "
                                         "5.87e-05° field of view"),
    ("0,4601.74685987,588.40125626", "0,4601.74685987,1e6", "section 'camera matrix' (cx, cy): principal point"),
    ("1024,1024", "1024,4", "section 'image size': image size 1024x4 px is not plausible"),
    ("1345.59296415", "1.5e4", "section 'translation': the X-ray source lies 1.5e+04 mm from the origin"),
    ("1345.59296415", "1_345.5", "non-numeric value '1_345.5' in section 'translation' (a plain decimal number"),
    ("1345.59296415", "0x10", "non-numeric value '0x10' in section 'translation'"),
    # Arabic-Indic digits: Python's float() reads them as 1345.5 (issue 44)
    ("1345.59296415", "\u0661\u0663\u0664\u0665.5", "non-numeric value '\u0661\u0663\u0664\u0665.5' in section "
                                                  "'translation' (a plain decimal number"),
    ("1024,1024", "1024,1024\n\nimage size\n640,480", "the section 'image size' appears twice; a MayaCam 2.0 file "
                                                     "has each once"),
])
def test_implausible_mayacam2_is_refused_naming_the_field(tmp_path, old, new, words):
    assert MAYACAM2.count(old) == 1
    assert_error(write(tmp_path, MAYACAM2.replace(old, new)), words)


@pytest.mark.parametrize("text, words", [
    ("JT_INTCALIB\n1e-300\n0\n0\n0.3\n", "JT_INTCALIB principal distance: source-intensifier distance 1e-300 mm"),
    ("JT_INTCALIB\n1000\n0\n0\n50\n", "JT_INTCALIB pixel pitch: pixel pitch 50 mm is not plausible"),
    ("0,0,1e300\n0,0,0\n0,0,0\n33,25,-1200\n1,64,48\n", "line 1 (camera position): the X-ray source lies 1e+300 mm"),
    ("0,0,1000\n0,0,0\n0,0,0\n33,25,-0.01\n1,64,48\n", "line 4 (focal length Z): focal length fx = 0.01 px"),
    ("0,0,1000\n0,0,0\n0,0,0\n33,25,-1200\n1,1e12,48\n", "line 5 (width, height): image size 1000000000000x48 px"),
    ("0,0,1000\n0,1e308,0\n0,0,0\n33,25,-1200\n1,64,48\n", "line 2 (rotation angles): 1e+308° is beyond ±360°"),
    ("0,0,1000\n-361,0,0\n0,0,0\n33,25,-1200\n1,64,48\n", "line 2 (rotation angles): -361° is beyond ±360°"),
])
def test_implausible_jointtrack_and_mayacam1_are_refused_naming_the_field(tmp_path, text, words):
    assert_error(write(tmp_path, text), words)


def test_implausible_json_calibration_and_keys_twice(tmp_path):
    view = load_view(write(tmp_path, MAYACAM2))
    path = tmp_path / "cal.json"
    save_view_json(view, path)
    text = path.read_text()
    write(tmp_path, text.replace('"distance_mm": ', '"distance_mm": 1e-300, "x": ', 1), "far.json")
    assert_error(tmp_path / "far.json", "view.distance_mm: source-intensifier distance 1e-300 mm is not plausible")
    write(tmp_path, text.replace('"version": 1', '"version": 1, "version": 1'), "twice.json")
    assert_error(tmp_path / "twice.json", "calibration file: the key 'version' appears twice in one object")


def test_input_warnings_are_collected_once_each_for_the_app(tmp_path):
    """The desktop app shows the notes of what it just read in one dialog: each note once, in
    order; any other warning goes on as before."""
    import warnings

    from fluorogui.io.errors import collected_input_warnings, warn_input

    path = write(tmp_path, "Jt_IntCalib\n1200\n0\n0\n0.4\n")
    with pytest.warns(UserWarning, match="not an input note"):
        with collected_input_warnings() as notes:
            load_view(path)
            load_view(path)
            warn_input("b.txt", "second")
            warnings.warn(UserWarning("not an input note"), stacklevel=2)
    assert notes == [f"{path}: the header 'Jt_IntCalib' is not in capitals as JointTrack writes it; read as "
                     "JT_INTCALIB", "b.txt: second"]


def test_lower_case_jointtrack_headers_are_read_with_a_warning(tmp_path):
    from fluorogui.io.errors import InputWarning

    path = write(tmp_path, "Jt_IntCalib\n1200\n0\n0\n0.4\n")
    with pytest.warns(InputWarning) as caught:
        view = load_view(path)
    assert view.distance == 1200.0
    assert [str(w.message) for w in caught] == [
        f"{path}: the header 'Jt_IntCalib' is not in capitals as JointTrack writes it; read as JT_INTCALIB"]
    poses = write(tmp_path, "jt_euler_312\nx,y,z,a,b,c\n1,2,3,4,5,6\n", "poses.jts")
    with pytest.warns(InputWarning, match="the header 'jt_euler_312' is not in capitals"):
        assert load_jointtrack_poses(poses).shape == (1, 6)
