"""The engine, file formats, workflow and command line import with Qt unavailable, and the
import-linter layer contracts hold."""
from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

SCRIPT = textwrap.dedent(
    """
    import importlib
    import pkgutil
    import sys

    BLOCKED = ("PySide6", "pyvistaqt", "fluorogui.gui")

    class BlockQt:
        def find_spec(self, name, path=None, target=None):
            if any(name == b or name.startswith(b + ".") for b in BLOCKED):
                raise ImportError(f"blocked import of {name}")
            return None

    sys.meta_path.insert(0, BlockQt())
    try:
        import PySide6  # noqa: F401  (the blocker itself must work)
        sys.exit("the import blocker let PySide6 through")
    except ImportError:
        pass
    imported, failed = [], []
    for package_name in ("fluorogui.core", "fluorogui.io", "fluorogui.workflow", "fluorogui.simulation",
                         "fluorogui.reference", "fluorogui.cli"):
        package = importlib.import_module(package_name)
        for info in pkgutil.walk_packages(package.__path__, package_name + "."):
            try:
                importlib.import_module(info.name)
                imported.append(info.name)
            except Exception as exc:
                failed.append(f"{info.name}: {type(exc).__name__}: {exc}")
    leaked = [m for m in sys.modules if any(m == b or m.startswith(b + ".") for b in BLOCKED)]
    print("\\n".join(imported))
    if failed or leaked:
        sys.exit("\\n".join(failed + [f"leaked: {m}" for m in leaked]))
    """
)


def test_core_and_io_import_without_qt():
    result = subprocess.run(
        [sys.executable, "-c", SCRIPT], cwd=REPO, capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, f"modules that fail to import with Qt blocked:\n{result.stderr}"
    imported = result.stdout.split()
    assert "fluorogui.io.project.document" in imported and "fluorogui.core.records" in imported


def test_import_linter_contracts_hold():
    """The contracts in pyproject.toml ([tool.importlinter]): the layers (faces, workflow,
    simulation, io, core) and the engine's rooms, no Qt outside fluorogui.gui, and the
    independent references apart from the matcher."""
    lint = Path(sys.executable).with_name("lint-imports")
    result = subprocess.run([str(lint), "--config", str(REPO / "pyproject.toml")], cwd=REPO,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-2000:]
    assert "Contracts: 4 kept, 0 broken" in result.stdout, result.stdout[-3000:]
    assert "The layers: the faces over the workflow" in result.stdout
    assert "independent references share no code" in result.stdout
