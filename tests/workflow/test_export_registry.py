"""The export registry (issue 45): a format declared in one module appears as a command-line
option, a check box of the app's export dialog and a row of the docs' table, is written by
both, and its declared needs (a frame rate, the poses it leaves out) act without code of its
own. The toy format lives in this test alone."""
from __future__ import annotations

import json
import os

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from fluorogui.cli.entry import main  # noqa: E402
from fluorogui.core.records import PoseRecord  # noqa: E402
from fluorogui.io.files import atomic_write_text  # noqa: E402
from fluorogui.workflow.exports import registry  # noqa: E402
from fluorogui.workflow.exports.registry import ExportFormat, ExportOptions, formats, write_exports  # noqa: E402
from fluorogui.workflow.exports.tables import in_statusless_files  # noqa: E402
from fluorogui.workflow.exports.timebase import require_frame_rate  # noqa: E402
from fluorogui.workflow.session import Session  # noqa: E402


def _write_toy(session, path, options):
    rate = require_frame_rate(session, path, options.fps)
    lines = []
    for frame in session.frames:
        record = session.project.poses.get((frame, "femoral"))
        keep = in_statusless_files(record, options.include_unreviewed)
        lines.append(json.dumps({"time": frame / rate, "pose": list(map(float, record.pose)) if keep else None}))
    atomic_write_text(path, "\n".join(lines) + "\n")
    return [path]


TOY = ExportFormat(name="toy", order=95, label="Toy poses (JSON lines)", default_name="{stem}_toy.jsonl",
                   metavar="OUT.jsonl", help="the femoral pose per frame as JSON lines", short="toy file",
                   timed=True, statusless=True, write=_write_toy)


@pytest.fixture
def toy(monkeypatch):
    formats()  # the real formats first
    monkeypatch.setitem(registry._REGISTRY, "toy", TOY)
    return TOY


@pytest.fixture
def project(tmp_path, capsys):
    assert main(["demo", str(tmp_path / "demo.fluoro"), "--frames", "2"]) == 0
    session = Session.open(tmp_path / "demo.fluoro")
    for frame in session.frames:  # matched poses without running the matcher
        session.project.poses[(frame, "femoral")] = PoseRecord([1.0 + frame, 2, 3, 4, 5, 6], status="matched")
    session.project.poses[(1, "femoral")] = PoseRecord([9.0, 9, 9, 9, 9, 9], status="needs_review", reason="test")
    session.save(tmp_path / "demo.fluoro")
    capsys.readouterr()
    return tmp_path / "demo.fluoro"


def test_the_real_formats_are_declared_once_each():
    names = [f.name for f in formats()]
    assert names == ["poses", "kinematics", "tra", "jts", "plot", "contact", "c3d", "trc", "condyles", "mot", "xromm"]
    assert [f.name for f in formats() if f.timed] == ["c3d", "trc", "condyles", "mot"]
    with pytest.raises(ValueError, match="two export formats"):
        registry.register(ExportFormat(name="tra", label="", default_name="", metavar="", help="",
                                       write=_write_toy))
    with pytest.raises(ValueError, match="must be a word"):
        registry.register(ExportFormat(name="my-format", label="", default_name="", metavar="", help="",
                                       write=_write_toy))


def test_a_toy_format_is_a_command_line_option_with_its_needs(toy, project, tmp_path, capsys):
    out = tmp_path / "toy.jsonl"
    # timed: refused without a frame rate, in one line, before any work
    assert main(["export", str(project), "--toy", str(out)]) == 2
    assert "--toy needs a frame rate" in capsys.readouterr().err and not out.exists()
    assert main(["export", str(project), "--toy", str(out), "--fps", "10"]) == 0
    captured = capsys.readouterr()
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["time"] for r in rows] == [0.0, 0.1]
    assert rows[0]["pose"] == [1.0, 2, 3, 4, 5, 6] and rows[1]["pose"] is None  # flagged: left out
    # statusless: the shared note names the format and the remedy
    assert ("1 pose flagged for review and left out of --toy as NaN (accept them in the app, or "
            "--include-unreviewed): frame 1") in captured.err
    assert f"wrote {out}" in captured.out
    assert main(["export", str(project), "--toy", str(out), "--fps", "10", "--include-unreviewed"]) == 0
    assert json.loads(out.read_text().splitlines()[1])["pose"] == [9.0, 9, 9, 9, 9, 9]
    assert "--toy OUT.jsonl" in _help(capsys) and "toy" not in _help(capsys, without_toy=True)


def _help(capsys, without_toy=False) -> str:
    if without_toy:
        registry._REGISTRY.pop("toy")
    with pytest.raises(SystemExit):
        main(["export", "--help"])
    return capsys.readouterr().out


def test_a_toy_format_is_a_check_box_of_the_export_dialog(toy, qtbot, tmp_path):
    from fluorogui.gui.dialogs.export_dialog import ExportDialog

    dialog = ExportDialog(tmp_path, "knee", 2)
    qtbot.addWidget(dialog)
    assert dialog.checks["toy"].text() == "Toy poses (JSON lines)" and not dialog.checks["toy"].isChecked()
    assert dialog.names["toy"].text() == "knee_toy.jsonl"
    dialog.checks["toy"].setChecked(True)
    assert dialog.time_note.text() == ("C3D, .trc, condyle markers, .mot and toy file need the frame rate: "
                                       "give it above.")
    assert dialog.targets()["toy"] == tmp_path / "knee_toy.jsonl"


def test_write_exports_writes_a_toy_format_from_a_script(toy, project, tmp_path):
    session = Session.open(project)
    written = write_exports(session, {"toy": tmp_path / "t.jsonl", "tra": tmp_path / "t.tra"},
                            ExportOptions(fps=25.0))
    assert written == [tmp_path / "t.tra", tmp_path / "t.jsonl"]  # in the registry's order
    assert json.loads((tmp_path / "t.jsonl").read_text().splitlines()[1])["time"] == 0.04


def test_the_docs_table_lists_a_toy_format(toy):
    pytest.importorskip("docutils")
    import sys
    from pathlib import Path

    from docutils.core import publish_doctree
    from docutils.parsers.rst import directives

    sys.path.insert(0, str(Path(__file__).parents[2] / "docs" / "_ext"))
    from export_formats import ExportFormats

    directives.register_directive("export-formats", ExportFormats)
    text = publish_doctree(".. export-formats::\n").astext()
    assert "--toy OUT.jsonl" in text and "Toy poses (JSON lines)" in text and "a frame rate" in text
    assert text.index("--xromm") < text.index("--toy")


def test_export_contact_is_what_kinematics_contact_gives_from_the_same_poses(project, tmp_path, capsys):
    """``fluorogui export --contact`` (issue 47) through the registry, against the independent
    path of ``fluorogui kinematics --contact`` on the project's poses written out."""
    import csv

    session = Session.open(project)
    for frame in session.frames:  # every pose matched: both paths give every row's values
        session.project.poses[(frame, "femoral")] = PoseRecord([1.0 + frame, 2, 3, 4, 5, 6], status="matched")
        session.project.poses[(frame, "tibial")] = PoseRecord([0.0, 1, -40 + frame, 0, 3, 0], status="matched")
    session.save(project)
    poses = tmp_path / "poses.csv"
    with open(poses, "w", newline="") as handle:
        out = csv.writer(handle)
        out.writerow(["frame", "component", "x", "y", "z", "alpha", "beta", "gamma"])
        for frame in session.frames:
            for c in ("femoral", "tibial"):
                out.writerow([frame, c, *session.project.poses[(frame, c)].pose])
    meshes = [str(session.project.model(c).mesh_path) for c in ("femoral", "tibial")]
    assert main(["export", str(project), "--contact", str(tmp_path / "a.csv"), "--liftoff-mm", "2.5",
                 "--side", "right"]) == 0
    assert main(["kinematics", "--poses", str(poses), "--side", "right", "--femoral-mesh", meshes[0],
                 "--tibial-mesh", meshes[1], "--contact", str(tmp_path / "b.csv"), "--liftoff-mm", "2.5"]) == 0
    capsys.readouterr()

    def table(name):
        lines = [line for line in (tmp_path / name).read_text().splitlines() if not line.startswith("#")]
        return list(csv.DictReader(lines))

    a, b = table("a.csv"), table("b.csv")
    assert [r["frame"] for r in a] == [r["frame"] for r in b] == ["0", "1"]
    for ra, rb in zip(a, b):
        for key in ("medial_x_mm", "medial_y_mm", "medial_z_mm", "lateral_x_mm", "lateral_y_mm", "lateral_z_mm"):
            assert abs(float(ra[key]) - float(rb[key])) < 1e-6, key
        assert ra["liftoff"] == rb["liftoff"]
    # a contact option without --contact is a usage error, before any work
    assert main(["export", str(project), "--poses", str(tmp_path / "p.csv"), "--liftoff-mm", "2"]) == 2
    assert "--liftoff-mm goes with --contact" in capsys.readouterr().err
    assert main(["export", str(project), "--contact", str(tmp_path / "c.csv"), "--liftoff-mm", "0"]) == 2
    assert "out of range" in capsys.readouterr().err
