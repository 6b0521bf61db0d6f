"""Importing a session from files: real biplane folder, synthetic sets, and every bad input."""
from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from fluorogui.io.errors import InputError
from fluorogui.io.images import read_image, write_image
from fluorogui.io.importer import (
    detect_biplane_folder,
    detect_single_plane_folder,
    extract_video_frames,
    import_folder,
    import_session,
    list_image_files,
    read_pairs_csv,
)
from fluorogui.io.project.document import load_project, save_project
from fluorogui.simulation.demo import build_demo_project, write_stl
from fluorogui.simulation.phantoms import tibial_component_mesh

SIZE = 96  # small demo images keep these tests fast


def error_of(function, *args, **kwargs) -> InputError:
    with pytest.raises(InputError) as info:
        function(*args, **kwargs)
    return info.value


@pytest.fixture(scope="module")
def demo_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("session")
    build_demo_project(folder, frames=3, image_size=SIZE)
    return folder


@pytest.fixture
def session(demo_folder, tmp_path):
    """A private copy of a small demo session to spoil, and its import arguments."""
    folder = tmp_path / "session"
    shutil.copytree(demo_folder, folder)
    arguments = {
        "calibrations": [folder / "calibration" / "cam1.json", folder / "calibration" / "cam2.json"],
        "image_sources": [folder / "cam1", folder / "cam2"],
        "models": {"femoral": folder / "models" / "femoral_component.stl",
                   "tibial": folder / "models" / "tibial_component.stl"},
    }
    return folder, arguments


# -- real data --------------------------------------------------------------------------------
def test_real_biplane_folder_imports_33_frames(shared_data):
    folder = shared_data / "biplane-tka"
    arguments = detect_biplane_folder(folder)
    assert arguments == {
        "calibrations": [folder / "calibration" / "cam1_mayacam2.txt", folder / "calibration" / "cam2_mayacam2.txt"],
        "image_sources": [folder / "cam1", folder / "cam2"],
        "models": {"femoral": folder / "models" / "femoral_component.stl",
                   "tibial": folder / "models" / "tibial_component.stl"},
        "pairs_csv": folder / "pairs.csv",
    }
    project = import_session(**arguments)
    with open(folder / "pairs.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 33
    assert project.frames == [int(r["frame"]) for r in rows]
    assert project.sequences[0].paths == [folder / r["cam1"] for r in rows]
    assert project.sequences[1].paths == [folder / r["cam2"] for r in rows]
    assert project.sequences[1].paths[0] == folder / "cam2" / "000522.tif"
    assert [v.image_size for v in project.views] == [(1024, 1024), (1024, 1024)]
    assert {m.component: m.mesh_path for m in project.models} == arguments["models"]


def test_real_biplane_folders_without_pairs_pair_in_name_order(shared_data):
    folder = shared_data / "biplane-tka"
    arguments = detect_biplane_folder(folder)
    arguments["pairs_csv"] = None
    project = import_session(**arguments)
    assert project.frames == list(range(33))
    assert project.sequences[0].paths == sorted((folder / "cam1").glob("*.tif"))
    assert project.sequences[1].paths[-1] == folder / "cam2" / "001042.tif"


# -- synthetic sessions ---------------------------------------------------------------------------
def test_folder_session_imports_and_round_trips_the_demo(session, tmp_path):
    folder, arguments = session
    project = import_session(**arguments)
    demo = load_project(folder / "demo.fluoro")
    assert project.frames == demo.frames == [0, 1, 2]
    assert project.sequences == demo.sequences
    assert [v.to_dict() for v in project.views] == [v.to_dict() for v in demo.views]
    assert project.models == demo.models
    assert not project.poses and not project.records
    # the demo folder is itself a biplane folder, pairs CSV included
    detected = detect_biplane_folder(folder)
    assert detected == {**arguments, "pairs_csv": folder / "pairs.csv"}
    assert import_session(**detected).sequences == demo.sequences


def test_explicit_file_lists_keep_their_order(session):
    folder, arguments = session
    cam1 = sorted((folder / "cam1").iterdir())
    cam2 = sorted((folder / "cam2").iterdir())
    arguments["image_sources"] = [cam1[::-1], cam2[::-1]]
    project = import_session(**arguments)
    assert project.sequences[0].paths == cam1[::-1] and project.frames == [0, 1, 2]


def test_mismatched_counts_name_the_folder_and_the_counts(session):
    folder, arguments = session
    (folder / "cam2" / "frame_002.png").unlink()
    error = error_of(import_session, **arguments)
    assert error.path == str(folder / "cam2")
    assert "has 2 images" in error.problem and "has 3" in error.problem and str(folder / "cam1") in error.problem


def test_wrong_image_size_names_the_image(session):
    folder, arguments = session
    write_image(folder / "cam2" / "frame_000.png", np.zeros((SIZE, SIZE + 8)))
    error = error_of(import_session, **arguments)
    assert error.path == str(folder / "cam2" / "frame_000.png")
    assert f"{SIZE + 8}x{SIZE}" in error.problem and f"{SIZE}x{SIZE}" in error.problem


def test_nan_calibration_names_the_file(session):
    folder, arguments = session
    path = arguments["calibrations"][1]
    document = json.loads(path.read_text())
    document["view"]["source_mm"][0] = float("nan")
    path.write_text(json.dumps(document))
    error = error_of(import_session, **arguments)
    assert error.path == str(path) and "NaN" in error.problem


def test_nan_in_a_mayacam_file_names_the_file(session):
    folder, arguments = session
    path = folder / "calibration" / "bad_mayacam2.txt"
    path.write_text("image size\n96,96\n\ncamera matrix\n400,0,48\n0,400,nan\n0,0,1\n\n"
                    "rotation\n1,0,0\n0,1,0\n0,0,1\n\ntranslation\n0\n0\n1000\n")
    arguments["calibrations"][0] = path
    error = error_of(import_session, **arguments)
    assert error.path == str(path) and "NaN" in error.problem


def test_missing_and_implausible_models_name_the_file(session, tmp_path):
    folder, arguments = session
    missing = folder / "models" / "nope.stl"
    arguments["models"]["tibial"] = missing
    error = error_of(import_session, **arguments)
    assert error.path == str(missing) and "not found" in error.problem

    vertices, faces = tibial_component_mesh()
    in_cm = tmp_path / "tibia_cm.stl"
    write_stl(in_cm, vertices / 10.0, faces)  # ~10 mm: loads, but no knee implant is that small
    arguments["models"]["tibial"] = in_cm
    error = error_of(import_session, **arguments)
    assert error.path == str(in_cm) and "knee-implant" in error.problem and "mm" in error.problem


def test_missing_and_empty_image_sources(session, tmp_path):
    folder, arguments = session
    arguments["image_sources"][0] = tmp_path / "absent"
    error = error_of(import_session, **arguments)
    assert error.path == str(tmp_path / "absent") and "not found" in error.problem
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "notes.txt").write_text("no images here")
    arguments["image_sources"][0] = empty
    error = error_of(import_session, **arguments)
    assert error.path == str(empty) and "no image files" in error.problem
    arguments["image_sources"][0] = [folder / "cam1" / "frame_000.png", folder / "notes.txt"]
    (folder / "notes.txt").write_text("x")
    error = error_of(import_session, **arguments)
    assert error.path == str(folder / "notes.txt") and "unsupported image type" in error.problem


def test_a_blank_only_image_is_refused_and_a_blank_first_frame_warned_about(session):
    """A view whose only image is blank cannot be matched at all: refused, naming it. A
    sequence may begin before the beam: its blank first frame is a warning, and tracking
    refuses each blank frame it is given (issue 44)."""
    from fluorogui.io.errors import InputWarning

    folder, arguments = session
    first = sorted((folder / "cam2").iterdir())[0]
    write_image(first, np.zeros((SIZE, SIZE)))
    with pytest.warns(InputWarning) as caught:
        import_session(**arguments)
    assert [str(w.message) for w in caught] == [f"{first}: the image is blank (every pixel 0): it shows nothing to "
                                                "match; its frame cannot be matched (the others are checked when "
                                                "they are)"]
    error = error_of(import_session, **{**arguments, "image_sources": [arguments["image_sources"][0], first]},
                     allow_unequal=True)
    assert error.path == str(first) and error.problem.startswith("the image is blank (every pixel 0)")


def test_folder_listing_is_natural_and_skips_other_files(tmp_path):
    for name in ("frame_10.png", "frame_2.png", "frame_1.png", ".hidden.png", "readme.txt"):
        write_image(tmp_path / name, np.zeros((4, 4))) if name.endswith(".png") else (tmp_path / name).write_text("")
    assert [p.name for p in list_image_files(tmp_path)] == ["frame_1.png", "frame_2.png", "frame_10.png"]


def test_pairs_csv_decides_frames_and_reports_its_errors(session):
    folder, arguments = session
    csv_path = folder / "pairs.csv"
    csv_path.write_text("frame,cam1,cam2\n5,cam1/frame_000.png,cam2/frame_001.png\n"
                        "9,cam1/frame_002.png,cam2/frame_002.png\n")
    project = import_session(arguments["calibrations"], [], arguments["models"], pairs_csv=csv_path)
    assert project.frames == [5, 9]
    assert project.sequences[1].paths == [folder / "cam2" / "frame_001.png", folder / "cam2" / "frame_002.png"]

    bad_lines = {
        "frame,cam1,cam2\nfive,cam1/frame_000.png,cam2/frame_000.png\n": "not a whole number",
        "frame,cam1,cam2\n1,cam1/frame_000.png\n": "line 2 has 2 columns",
        "frame,cam1,cam2\n1,cam1/frame_000.png,cam2/frame_000.png\n1,cam1/frame_001.png,cam2/frame_001.png\n":
            "repeats frame 1",
        "frame,cam1,cam2\n": "no image pairs",
    }
    for text, problem in bad_lines.items():
        csv_path.write_text(text)
        error = error_of(read_pairs_csv, csv_path)
        assert error.path == str(csv_path) and problem in error.problem
    csv_path.write_text("frame,cam1,cam2\n0,cam1/frame_000.png,cam2/missing.png\n")
    error = error_of(import_session, arguments["calibrations"], [], arguments["models"], pairs_csv=csv_path)
    assert error.path == str(folder / "cam2" / "missing.png") and "pairs.csv" in error.problem


def write_video(path, levels):
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10, (SIZE, SIZE), isColor=False)
    if not writer.isOpened():
        pytest.skip("OpenCV has no AVI writer here")
    for level in levels:
        writer.write(np.full((SIZE, SIZE), level, np.uint8))
    writer.release()


def test_video_source_is_read_lazily(session, tmp_path):
    folder, arguments = session
    video = tmp_path / "cam2.avi"
    write_video(video, (40, 120, 200))
    arguments["image_sources"][1] = video
    project = import_session(**arguments)
    frames = project.sequences[1].paths
    assert frames == [Path(f"{video}@{k}") for k in range(3)]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cam2.avi", "session"]  # nothing extracted
    assert abs(float(read_image(frames[2]).mean()) * 255 - 200) < 8
    saved = tmp_path / "session" / "lazy.fluoro"
    save_project(project, saved)
    assert load_project(saved).sequences[1].paths == frames


def test_video_frame_count_must_match(session, tmp_path):
    _, arguments = session
    video = tmp_path / "cam2.avi"
    write_video(video, (40, 120))  # the other camera has 3 images
    arguments["image_sources"][1] = video
    error = error_of(import_session, **arguments)
    assert error.path == str(video) and "has 2 images" in error.problem and "3" in error.problem


def test_extract_video_frames_still_available(tmp_path):
    video = tmp_path / "clip.avi"
    write_video(video, (40, 200))
    frames = extract_video_frames(video)
    assert [p.name for p in frames] == ["frame_000000.png", "frame_000001.png"]
    assert abs(cv2.imread(str(frames[1]), 0).mean() - 200) < 8


def test_single_plane_real_folder(shared_data):
    folder = shared_data / "single-plane-tka"
    found = detect_single_plane_folder(folder)
    assert found["calibrations"] == [folder / "calibration.txt"]
    assert found["image_sources"] == [folder]
    assert found["models"] == {"femoral": folder / "KR_right_7_fem.stl", "tibial": folder / "KR_right_6_tib.stl"}
    project = import_folder(folder)
    assert len(project.views) == 1 and project.frames == [0, 1, 2]
    assert [p.name for p in project.sequences[0].paths] == [f"AT_K1_V1_0{n}.tif" for n in (160, 170, 180)]
    assert project.views[0].distance == 1198.0 and project.views[0].pitch == (0.373, 0.373)


def test_single_plane_folder_with_image_folder(session, tmp_path):
    folder, arguments = session
    single = tmp_path / "single"
    single.mkdir()
    shutil.copy(arguments["calibrations"][0], single / "calibration.json")
    shutil.copytree(folder / "cam1", single / "images")
    shutil.copytree(folder / "models", single / "models")
    assert detect_biplane_folder(single) is None
    project = import_folder(single)
    assert len(project.views) == 1 and len(project.frames) == 3 and len(project.models) == 2
    (single / "calibration.json").unlink()
    assert "not a session folder" in error_of(import_folder, single).problem


def test_detect_rejects_other_folders(tmp_path, session):
    assert detect_biplane_folder(tmp_path / "absent") is None
    assert detect_biplane_folder(tmp_path) is None  # no calibration/, no cam folders
    folder, _ = session
    shutil.rmtree(folder / "calibration")
    assert detect_biplane_folder(folder) is None


def test_detect_accepts_view_folders_and_no_models(tmp_path, session):
    folder, _ = session
    (folder / "cam1").rename(folder / "View1")
    (folder / "cam2").rename(folder / "View2")
    for k in (1, 2):
        (folder / "calibration" / f"cam{k}.json").rename(folder / "calibration" / f"calib_{k}.json")
    shutil.rmtree(folder / "models")
    (folder / "pairs.csv").unlink()
    found = detect_biplane_folder(folder)
    assert found == {
        "calibrations": [folder / "calibration" / "calib_1.json", folder / "calibration" / "calib_2.json"],
        "image_sources": [folder / "View1", folder / "View2"],
        "models": {},
        "pairs_csv": None,
    }
