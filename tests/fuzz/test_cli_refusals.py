"""The command line's one error path: every bad option or input file is one line on stderr
naming it, exit 2, before any work; internal errors are one line naming the log file
(traceback inside); library chatter goes to the log unless --verbose."""
from __future__ import annotations

import os
import threading
from pathlib import Path

import numpy as np
import pytest

from fluorogui import cli
from fluorogui.core.projection.geometry import View
from fluorogui.io.calibration import save_view_json
from fluorogui.io.images import write_image

CORPUS = Path(__file__).resolve().parent / "corpus"


@pytest.fixture(autouse=True)
def log_folder(tmp_path, monkeypatch):
    monkeypatch.setenv("FLUOROGUI_DATA_DIR", str(tmp_path / "data"))
    return tmp_path / "data" / "logs" / "fluorogui.log"


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    views = [View.looking_at((0, -1000, 0), (0, 0, 0), (0, 0, 1), 1200, image_size=(64, 48), pitch=0.4, name="a"),
             View.looking_at((1000, 0, 0), (0, 0, 0), (0, 0, 1), 1200, image_size=(64, 48), pitch=0.4, name="b")]
    out = {"dir": d}
    for k, view in enumerate(views):
        save_view_json(view, d / f"cam{k}.json")
        write_image(d / f"img{k}.png", np.linspace(0, 1, 48 * 64).reshape(48, 64), bits=8)  # not blank
    import pyvista as pv

    pv.Sphere(radius=20.0).save(d / "ball.stl")
    (d / "pairs.csv").write_text("frame,cam1,cam2\n0,img0.png,img1.png\n")
    (d / "ref.csv").write_text("frame,component,x,y,z,alpha,beta,gamma\n0,femoral,1,2,3,4,5,6\n")
    return out


def match_args(files, *extra, model=None):
    d = files["dir"]
    return ["match", "--camera", str(d / "cam0.json"), "--camera", str(d / "cam1.json"),
            "--image", str(d / "img0.png"), "--image", str(d / "img1.png"),
            "--model", str(model or d / "ball.stl"), "--start", "0", "0", "0", "0", "0", "0", *extra]


def repeat_args(files, *extra, pairs=None, reference=None):
    d = files["dir"]
    return ["validate", "repeatability", "--camera", str(d / "cam0.json"), "--camera", str(d / "cam1.json"),
            "--model", str(d / "ball.stl"), "--reference", str(reference or d / "ref.csv"),
            "--pairs", str(pairs or d / "pairs.csv"), "--component", "femoral", "--starts", "1", *extra]


def one_line(capsys, argv, code=2) -> str:
    assert cli.main(argv) == code
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert "Traceback" not in captured.err
    return lines[0]


@pytest.mark.parametrize("option, value, words", [
    ("--starts", "0", "argument --starts: 0 is out of range; give 1 to 1000"),
    ("--starts", "1001", "argument --starts: 1001 is out of range; give 1 to 1000"),
    ("--starts", "ten", "argument --starts: 'ten' is not a whole number"),
    ("--outline-points", "-5", "argument --outline-points: -5 is out of range; give 1 to 100000"),
    ("--points", "0", "argument --points: 0 is out of range; give 10 to 5000000"),
])
def test_option_ranges(files, capsys, option, value, words):
    assert one_line(capsys, match_args(files, option, value)) == f"fluorogui match: {words}"


def test_workers_and_start_values(files, capsys):
    assert one_line(capsys, ["track", "x.fluoro", "--workers", "0"]) == \
        "fluorogui track: argument --workers: 0 is out of range; give 1 to 256"
    argv = match_args(files)
    argv[argv.index("--start") + 1] = "inf"
    assert one_line(capsys, argv) == "fluorogui match: argument --start: 'inf' is NaN or infinite; give a finite number"


def test_mesh_claiming_billions_is_refused(files, capsys):
    line = one_line(capsys, match_args(files, model=CORPUS / "billions.ply"))
    assert line.startswith(f"fluorogui: error: {CORPUS / 'billions.ply'}: unreadable mesh file: the header claims")


def test_unwritable_out_is_found_before_the_work(files, capsys, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    line = one_line(capsys, repeat_args(files, "--out", str(blocker / "results")))
    assert line == (f"fluorogui: error: {blocker / 'results'}: cannot write results here: "
                    "a part of the path is not a folder")


def test_ragged_and_binary_pairs(files, capsys, tmp_path):
    ragged = tmp_path / "pairs.csv"
    ragged.write_text("frame,cam1,cam2\n0,a.png\n")
    assert one_line(capsys, repeat_args(files, pairs=ragged)) == (
        f"fluorogui: error: {ragged}: line 2 has 2 columns, expected 3 (frame, one image per view)")
    binary = tmp_path / "binary.csv"
    binary.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR")
    assert one_line(capsys, repeat_args(files, pairs=binary)) == \
        f"fluorogui: error: {binary}: binary file, not a text CSV file"


def test_reference_csv_problems(files, capsys, tmp_path):
    ref = tmp_path / "ref.csv"
    ref.write_text("frame,component,x,y,z,alpha,beta\n0,femoral,1,2,3,4,5\n")
    assert one_line(capsys, repeat_args(files, reference=ref)) == (
        f"fluorogui: error: {ref}: line 1: the header lacks the column gamma "
        "(expected frame,component,x,y,z,alpha,beta,gamma)")
    ref.write_text("frame,component,x,y,z,alpha,beta,gamma\n0,femoral,1,2,3,4,5\n")
    assert one_line(capsys, repeat_args(files, reference=ref)) == \
        f"fluorogui: error: {ref}: line 2 has 7 values; the header has 8"
    ref.write_text("frame,component,x,y,z,alpha,beta,gamma\n0,femoral,1,2,3,4,5,nan\n")
    assert one_line(capsys, repeat_args(files, reference=ref)) == \
        f"fluorogui: error: {ref}: line 2: column 'gamma' is not a finite number: 'nan'"


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="POSIX FIFOs")
def test_fifo_calibration_does_not_block(files, capsys, tmp_path):
    fifo = tmp_path / "cam.txt"
    os.mkfifo(fifo)
    argv = match_args(files)
    argv[argv.index("--camera") + 1] = str(fifo)
    codes = []
    worker = threading.Thread(target=lambda: codes.append(cli.main(argv)), daemon=True)
    worker.start()
    worker.join(10)
    assert codes == [2]
    assert capsys.readouterr().err.strip() == \
        f"fluorogui: error: {fifo}: is not a regular file (a pipe, socket or device); give a calibration file"


def test_internal_error_names_the_log_and_keeps_the_traceback(files, capsys, monkeypatch, log_folder):
    def broken(args):
        raise RuntimeError("a bug\nover two lines")

    monkeypatch.setattr("fluorogui.cli.match.run", broken)
    line = one_line(capsys, match_args(files), code=1)
    assert line == f"fluorogui: internal error: RuntimeError: a bug over two lines; details in {log_folder}"
    log = log_folder.read_text()
    assert "Traceback" in log and "raise RuntimeError" in log


@pytest.mark.skipif(os.name != "posix", reason="file descriptors")
def test_native_chatter_goes_to_the_log_unless_verbose(files, capfd, monkeypatch, log_folder):
    def noisy(args):
        os.write(2, b"libpng warning: iCCP: known incorrect sRGB profile\n")
        return 0

    monkeypatch.setattr("fluorogui.cli.match.run", noisy)
    assert cli.main(match_args(files)) == 0
    assert "libpng" not in capfd.readouterr().err
    assert "libpng warning" in log_folder.read_text()
    assert cli.main(["--verbose", *match_args(files)]) == 0
    assert "libpng warning" in capfd.readouterr().err


def test_an_os_error_on_a_named_path_is_a_refusal_naming_it(files, capsys, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    line = one_line(capsys, ["demo", str(blocker / "sub" / "d.fluoro")])
    assert line == f"fluorogui: error: {blocker / 'sub'}: a part of the path is not a folder"


# -- the issue's regression cases: each message names the input at fault ------------------------
EXPECTED = {  # case -> the one line on stderr, after "fluorogui: error: <calibration file>: " for files
    "width_1e12": "section 'image size': image size 1000000000000x48 px is not plausible for a fluoroscope "
                  "(8 to 32,768 px a side)",
    "focal_1e-12": "section 'camera matrix' (fx, fy): focal length fx = 1e-12 px gives a 180° field of view across "
                   "64 px; a fluoroscope's is 0.1° to 120°",
    "translation_1e300": "section 'translation': the X-ray source lies 1e+300 mm from the origin; a fluoroscope's "
                         "calibration puts it within 10 m",
    "underscore_number": "non-numeric value '1_000' in section 'image size' (a plain decimal number is expected)",
    "huge_integer": "section 'image size': image size 99999999999999991611392x48 px is not plausible for a "
                    "fluoroscope (8 to 32,768 px a side)",
    "jointtrack_pitch_1e-300": "JT_INTCALIB pixel pitch: pixel pitch 1e-300 mm is not plausible for a fluoroscope "
                               "(0.001 to 10 mm)",
    "jointtrack_offset_1e300": "JT_INTCALIB principal point offsets: principal point (2.5e+300, 512) px lies more "
                               "than an image size outside the 1024x1024 px image",
    "start_behind_source": "fluorogui: --start: the pose lies behind the source of view 1 (its centre is 100 mm "
                           "behind it)",
    "start_at_source": "fluorogui: --start: the pose lies at the source of view 1 (its centre is 5 mm in front of "
                       "it, within the component's size)",
    "start_half_way_to_source": "fluorogui: --start: the pose puts the component outside this image of view 2 (",
    "start_1e5_mm_away": "fluorogui: --start: the pose lies too far from the source of view 1 (1.01e+05 mm from it): "
                         "the component would be 1.2 px across",
    "jointtrack_lower_case_header": "the header 'jt_intcalib' is not in capitals as JointTrack writes it; read as "
                                    "JT_INTCALIB",
}


# issue 44: the whole line, {cases} and {scene} standing for the folders; "..." at the end: its start
ISSUE_44 = {
    "image_all_0_tiff": "fluorogui: error: {cases}/image_all_0_tiff.tif: the image is blank (every pixel 0): it "
                        "shows nothing to match",
    "image_all_255_tiff": "fluorogui: error: {cases}/image_all_255_tiff.tif: the image is blank (every pixel 255 of "
                          "255): it shows nothing to match",
    "jpeg_truncated": "fluorogui: error: {cases}/cut.jpg: damaged JPEG image: the decoder reports ...",
    "outline_5000_px_off": "fluorogui: error: {cases}/far_outline.csv: outline point 1 (5047, 24) px lies outside the "
                           "64x48 px image of view 1 (by more than 10% of its size): an outline of another image?",
    "calibration_image_size_twice": "fluorogui: error: {cases}/twice.txt: the section 'image size' appears twice; a "
                                    "MayaCam 2.0 file has each once",
    "calibration_arabic_indic_digits": "fluorogui: error: {cases}/arabic.txt: non-numeric value '\u0666\u0664' in "
                                       "section 'image size' (a plain decimal number is expected)",
    "mayacam1_angle_1e308": "fluorogui: error: {cases}/angle_1e308.txt: line 2 (rotation angles): 1e+308° is beyond "
                            "±360°; give the camera's rotations in degrees",
    "mesh_one_triangle_10_mm": "fluorogui: error: {cases}/triangle.stl: mesh has 1 triangle of non-zero area; a "
                               "surface enclosing a solid needs at least 4, and an implant model has thousands",
    "start_seven_numbers": "fluorogui match: argument --start: takes exactly 6 numbers (X Y Z ALPHA BETA GAMMA), got 7",
    "start_angles_1e6": "fluorogui: --start: ALPHA = 1e+06° is beyond ±360°; give the angles in degrees",
    "pairs_lists_a_blank_image": "fluorogui: error: {cases}/blank.tif: the image is blank (every pixel 0): it shows "
                                 "nothing to match (listed in {cases}/pairs_lists_a_blank_image.csv for frame 0)",
    "pairs_lists_a_csv": "fluorogui: error: {scene}/outline0.csv: unsupported image type '.csv' (use TIFF, PNG, JPEG, "
                         "BMP or DICOM) (listed on line 2 of pairs_lists_a_csv.csv)",
}


@pytest.fixture(scope="module")
def regressions(tmp_path_factory):
    from cli_cases import make_scene, regression_cases

    folder = tmp_path_factory.mktemp("regressions")
    cases = {name: (argv, expect, names) for name, argv, expect, names in
             regression_cases(make_scene(folder / "scene"), folder / "cases")}
    return cases | {"folder": folder}


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_messages_name_the_input_at_fault(regressions, capsys, name):
    from cli_cases import judge

    argv, expect, names = regressions[name]
    code = cli.main(argv)
    err = capsys.readouterr().err.strip()
    assert judge((argv, expect, names), {"code": code, "stderr": err}) == "ok", err
    if expect == "warned":
        assert err == f"fluorogui: warning: {names[0]}: {EXPECTED[name]}"
    elif names == ["--start"]:
        assert err.startswith(EXPECTED[name]), err
    else:
        assert err == f"fluorogui: error: {names[0]}: {EXPECTED[name]}"


@pytest.mark.parametrize("name", sorted(ISSUE_44))
def test_bad_inputs_of_issue_44_are_refused_by_name(regressions, capsys, name):
    from cli_cases import judge

    argv, expect, names = regressions[name]
    code = cli.main(argv)
    err = capsys.readouterr().err.strip()
    assert judge((argv, expect, names), {"code": code, "stderr": err}) == "ok", err
    folder = regressions["folder"]
    line = ISSUE_44[name].format(cases=folder / "cases", scene=folder / "scene")
    if line.endswith("..."):
        assert err.startswith(line[:-3]), err
    else:
        assert err == line
