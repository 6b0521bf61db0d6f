"""The import dialog: OK imports or shows the problem inline; "From folder" fills every field."""
from __future__ import annotations

import pytest

pytest.importorskip("pytestqt")
from PySide6.QtWidgets import QDialog, QFileDialog  # noqa: E402

from fluorogui.gui.dialogs.import_dialog import FIELD_KEYS, ImportDialog  # noqa: E402
from fluorogui.simulation.demo import build_demo_project  # noqa: E402


@pytest.fixture(scope="module")
def demo_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("session")
    build_demo_project(folder, frames=2, image_size=96)
    return folder


def good_paths(folder) -> dict:
    return {
        "calibration1": folder / "calibration" / "cam1.json",
        "calibration2": folder / "calibration" / "cam2.json",
        "images1": folder / "cam1",
        "images2": sorted((folder / "cam2").iterdir()),  # an explicit list of files
        "femoral": folder / "models" / "femoral_component.stl",
        "tibial": folder / "models" / "tibial_component.stl",
    }


@pytest.fixture
def dialog(qtbot):
    widget = ImportDialog()
    qtbot.addWidget(widget)
    widget.show()
    qtbot.waitExposed(widget)
    return widget


def test_good_paths_import_and_accept(dialog, demo_folder):
    dialog.fill(**good_paths(demo_folder))
    dialog.accept()
    assert dialog.result() == QDialog.DialogCode.Accepted and not dialog.isVisible()
    assert dialog.project is not None and dialog.project.frames == [0, 1]
    assert dialog.project.sequences[1].paths == sorted((demo_folder / "cam2").iterdir())
    assert sorted(m.component for m in dialog.project.models) == ["femoral", "tibial"]
    assert "kinematics" not in dialog.project.settings  # the side was not chosen


def test_the_chosen_knee_side_goes_into_the_project(dialog, demo_folder):
    dialog.fill(**good_paths(demo_folder))
    dialog.side.setCurrentIndex(dialog.side.findData("left"))
    dialog.accept()
    assert dialog.project.settings["kinematics"]["side"] == "left"


def test_bad_path_shows_the_error_inline_and_stays_open(dialog, demo_folder):
    paths = good_paths(demo_folder)
    missing = demo_folder / "models" / "missing.stl"
    dialog.fill(**{**paths, "tibial": missing})
    dialog.accept()
    assert dialog.isVisible() and dialog.result() != QDialog.DialogCode.Accepted
    assert dialog.project is None
    assert dialog.error_label.isVisible() and str(missing) in dialog.error_label.text()
    assert "border" in dialog.fields["tibial"].styleSheet()  # the field at fault is outlined
    # fixing the field clears the mark and the import goes through
    dialog.fill(tibial=paths["tibial"])
    assert dialog.fields["tibial"].styleSheet() == ""
    dialog.accept()
    assert dialog.result() == QDialog.DialogCode.Accepted and dialog.project is not None


def test_incomplete_form_says_what_is_missing(dialog, demo_folder):
    dialog.fill(calibration1=demo_folder / "calibration" / "cam1.json", images2=demo_folder / "cam2")
    dialog.accept()
    assert dialog.isVisible() and dialog.project is None
    text = dialog.error_label.text()
    assert "calibration of view 2" in text and "images of view 1" in text and "implant model" in text
    assert "calibration of view 1" not in text


def test_pairs_csv_makes_image_fields_optional(dialog, demo_folder):
    paths = good_paths(demo_folder)
    del paths["images1"], paths["images2"]
    dialog.fill(**paths, pairs_csv=demo_folder / "pairs.csv")
    dialog.accept()
    assert dialog.result() == QDialog.DialogCode.Accepted and dialog.project.frames == [0, 1]


def test_from_folder_with_a_non_session_folder_reports_it(dialog, tmp_path, monkeypatch):
    monkeypatch.setattr(QFileDialog, "getExistingDirectory", lambda *a, **k: str(tmp_path))
    dialog.from_folder_button.click()
    assert dialog.error_label.isVisible() and "not a session folder" in dialog.error_label.text()
    assert all(edit.text() == "" for edit in dialog.fields.values())


def test_from_folder_fills_every_field_from_real_data(dialog, shared_data, monkeypatch):
    folder = shared_data / "biplane-tka"
    monkeypatch.setattr(QFileDialog, "getExistingDirectory", lambda *a, **k: str(folder))
    dialog.from_folder_button.click()
    assert set(dialog.fields) == set(FIELD_KEYS)
    assert all(edit.text() for edit in dialog.fields.values()), {k: e.text() for k, e in dialog.fields.items()}
    assert dialog.fields["calibration2"].text() == str(folder / "calibration" / "cam2_mayacam2.txt")
    assert dialog.fields["images1"].text() == str(folder / "cam1")
    assert dialog.fields["pairs_csv"].text() == str(folder / "pairs.csv")
    dialog.accept()
    assert dialog.result() == QDialog.DialogCode.Accepted and len(dialog.project.frames) == 33


def test_every_field_has_a_tooltip(dialog):
    assert all(edit.toolTip() for edit in dialog.fields.values())
    assert dialog.from_folder_button.toolTip()


def test_previews_show_first_frame_count_format_and_depth(dialog, demo_folder, qtbot):
    dialog.fill(**good_paths(demo_folder))
    dialog.update_previews()
    assert not dialog.previews[1].pixmap().isNull() and not dialog.previews[2].pixmap().isNull()
    assert dialog.preview_texts[1].text() == "2 frames: PNG 96x96, 8-bit"
    dialog.fill(images2=demo_folder / "nowhere")
    qtbot.waitUntil(lambda: "not found" in dialog.preview_texts[2].text(), timeout=2000)  # after the debounce
    assert dialog.previews[2].pixmap().isNull()


def test_single_plane_folder_fills_view_1_and_imports(dialog, shared_data, monkeypatch):
    folder = shared_data / "single-plane-tka"
    monkeypatch.setattr(QFileDialog, "getExistingDirectory", lambda *a, **k: str(folder))
    dialog.from_folder_button.click()
    assert dialog.fields["calibration1"].text() == str(folder / "calibration.txt")
    assert dialog.fields["calibration2"].text() == "" and dialog.fields["images2"].text() == ""
    dialog.update_previews()
    assert dialog.preview_texts[1].text() == "3 frames: TIFF 1024x1024, 8-bit"
    dialog.accept()
    assert dialog.result() == QDialog.DialogCode.Accepted and len(dialog.project.views) == 1
