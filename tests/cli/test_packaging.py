"""The standalone build's inputs stay consistent (fast; the build itself is the
documented command ``python packaging/build.py --check``, which CI runs): icons in every
size, the desktop file and AppStream metadata, the spec's hidden imports and VTK modules
exist, what is loaded by name is kept, build.py leaves the environment's install alone,
and the check's generated inputs are what they say."""
import ast
import configparser
import importlib.util
import subprocess
import sys
import xml.etree.ElementTree as ET
from importlib.metadata import entry_points
from pathlib import Path

import numpy as np
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


def test_spec_keeps_what_is_loaded_by_name():
    """What the import scan cannot see: the Kinematics dock's Qt backend (not excluded),
    imagecodecs' codecs with every module they import, pylibjpeg's plugins."""
    hidden, excludes = _spec_constant("HIDDEN"), _spec_constant("EXCLUDES")
    assert "matplotlib.backends.backend_qtagg" in hidden and "matplotlib.backends.backend_qtagg" not in excludes
    codecs = set(_spec_constant("IMAGECODECS"))
    assert {"imagecodecs._imcd", "imagecodecs._jpeg8", "imagecodecs._zlib"} <= codecs  # LZW, JPEG, Deflate
    probe = ("import sys, imagecodecs; before = set(sys.modules)\n"
             f"for name in {sorted(codecs)!r}: __import__(name)\n"
             "print(' '.join(sorted(m for m in set(sys.modules) - before if m.startswith('imagecodecs'))))")
    loaded = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout.split()
    assert set(loaded) <= codecs, f"imported by the listed codecs but not listed: {sorted(set(loaded) - codecs)}"
    assert {"pylibjpeg", "libjpeg", "openjpeg"} <= set(hidden)
    decoders = {ep.name: ep.value for ep in entry_points(group="pylibjpeg.pixel_data_decoders")}
    assert decoders["1.2.840.10008.1.2.4.70"].startswith("libjpeg:")  # JPEG Lossless SV1, as the check writes
    assert decoders["1.2.840.10008.1.2.4.90"].startswith("openjpeg:")  # JPEG 2000 Lossless


def test_build_installs_only_the_build_tools(monkeypatch):
    """build.py never runs ``pip install -e``: that would re-point the environment's
    fluorogui at whichever checkout runs the build."""
    build = _build_module()
    requirements = build.build_requirements()
    assert requirements and all(r.lower().startswith("pyinstaller") for r in requirements)
    calls = []
    monkeypatch.setitem(sys.modules, "PyInstaller", None)  # as if PyInstaller were missing
    monkeypatch.setattr(build.subprocess, "run", lambda command, **kw: calls.append(command))
    build.ensure_build_tools()
    assert calls == [[sys.executable, "-m", "pip", "install", "-q", "--disable-pip-version-check", *requirements]]


def test_check_inputs_are_the_compressions_they_claim(tmp_path):
    """build.py --check's generated inputs: an LZW TIFF and a JPEG Lossless DICOM read back
    exactly; the probes are JPEG / Deflate TIFF and JPEG baseline / JPEG 2000 DICOM."""
    sys.path.insert(0, str(PACKAGING))
    try:
        import check_inputs
    finally:
        sys.path.remove(str(PACKAGING))
    from fluorogui.io.images import image_info, read_image

    pixels = (np.arange(40 * 56).reshape(40, 56) * 29 % 65536).astype(np.uint16)
    tiff = check_inputs.write_lzw_tiff(tmp_path / "a.tif", pixels)
    dicom = check_inputs.write_jpeg_lossless_dicom(tmp_path / "a.dcm", pixels)
    assert image_info(tiff).detail == "lzw" and "JPEG Lossless" in image_info(dicom).detail
    for path in (tiff, dicom):
        np.testing.assert_array_equal(np.round(read_image(path).astype(np.float64) * 65535), pixels)
    details = [image_info(p).detail for p in check_inputs.write_format_probes(tmp_path)]
    assert details[0] == "jpeg" and "deflate" in details[1]
    assert "JPEG Baseline" in details[2] and "JPEG 2000" in details[3]


def _build_module():
    spec = importlib.util.spec_from_file_location("fluorogui_build_script", PACKAGING / "build.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
