"""The standalone build's inputs stay consistent (fast; the build itself is the
documented command ``python packaging/build.py --check``): icons in every size, the
desktop file and AppStream metadata, the spec's hidden imports and VTK modules exist."""
import ast
import configparser
import importlib.util
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from fluorogui import __version__

PACKAGING = Path(__file__).resolve().parents[2] / "packaging"


def _spec_constant(name):
    tree = ast.parse((PACKAGING / "fluorogui.spec").read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == name for t in node.targets):
            value = node.value
            if isinstance(value, ast.Call):  # set("""...""".split())
                return set(ast.literal_eval(value.args[0].func.value).split())
            return ast.literal_eval(value)
    raise KeyError(name)


def test_icons_in_platform_sizes():
    from PIL import Image

    for size in (16, 24, 32, 48, 64, 128, 256, 512):
        with Image.open(PACKAGING / "icons" / f"fluorogui-{size}.png") as image:
            assert image.size == (size, size)
    with Image.open(PACKAGING / "icons" / "fluorogui.ico") as ico:
        assert (256, 256) in ico.info["sizes"] and (16, 16) in ico.info["sizes"]
    assert (PACKAGING / "icons" / "fluorogui.icns").stat().st_size > 1000


def test_desktop_file_and_appstream_metadata():
    desktop = configparser.ConfigParser(interpolation=None)
    desktop.optionxform = str
    desktop.read(PACKAGING / "fluorogui.desktop")
    entry = desktop["Desktop Entry"]
    assert entry["Type"] == "Application" and entry["Exec"].split()[0] == "fluorogui"
    assert entry["Icon"] == "fluorogui" and entry["Categories"].endswith(";")
    root = ET.parse(PACKAGING / "io.github.fluorogui.metainfo.xml").getroot()
    assert root.find("launchable").text == "fluorogui.desktop"
    assert root.find("releases/release").get("version") == __version__  # one version everywhere


def test_spec_hidden_imports_and_vtk_modules_exist():
    for name in _spec_constant("HIDDEN"):
        assert importlib.util.find_spec(name) is not None, name
    vtk = pytest.importorskip("vtkmodules")
    present = {p.name.split(".")[0][3:] for p in Path(vtk.__file__).parent.glob("vtk*.so")}
    missing = _spec_constant("VTK_KEEP") - present
    assert not missing, f"VTK modules the build keeps but VTK no longer has: {sorted(missing)}"
    for name in ("RenderingOpenGL2", "InteractionStyle", "IOGeometry", "IOPLY"):
        assert name in _spec_constant("VTK_KEEP")


def test_quick_start_page_is_package_data():
    from fluorogui.resources import ICON_DIR, resource_path

    assert "<!--SHORTCUTS-->" in resource_path("quickstart.html").read_text()
    assert (ICON_DIR / "app.svg").exists()
