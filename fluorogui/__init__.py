"""fluorogui: six-degree-of-freedom pose of knee-implant components from biplane fluoroscopy.

The public Python API is the workflow the desktop app and the command line use; it never
imports Qt. The names below are imported on first use, so ``import fluorogui`` stays
cheap:

``Session``
    One open project, its undo history and the work on it: find, match, track, store,
    kinematics (``fluorogui.workflow.session``).
``FrameResult``
    What matching one component in one frame produced (``fluorogui.workflow.results``).
``FrameState``
    How far the work on a frame has got (the timeline's colours).
``Status``
    A pose's status: ``matched``, ``needs_review``, ``failed`` or ``placed``.
``WorkflowSettings``
    The matcher, loop, quality and tracking settings kept in a project.
``Placement``
    Where *find implants* put a component, and how sure it is.
``build_demo_project``
    Write the built-in demo session (generated images with known true poses).
``import_folder``
    A project from a biplane or single-plane data folder.

Examples
--------
::

    from fluorogui import Session
    session = Session.open("knee.fluoro")
    for result in session.track(components="both", autosave=True):
        print(result.frame, result.component, result.status, result.pose)
"""


def _package_version() -> str:
    """The installed distribution's version (pyproject.toml is the one source); the
    fallback covers a source tree that was never installed."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("fluorogui")
    except PackageNotFoundError:
        return "0.0.0+unknown"


__version__ = _package_version()

_PUBLIC = {
    "Session": "fluorogui.workflow.session",
    "FrameState": "fluorogui.workflow.session",
    "FrameResult": "fluorogui.workflow.results",
    "Placement": "fluorogui.core.search.find",
    "WorkflowSettings": "fluorogui.workflow.settings",
    "Status": "fluorogui.core.status",
    "build_demo_project": "fluorogui.simulation.demo",
    "import_folder": "fluorogui.io.importer",
}
__all__ = ["__version__", *_PUBLIC]


def __getattr__(name):
    if name in _PUBLIC:
        import importlib

        value = getattr(importlib.import_module(_PUBLIC[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'fluorogui' has no attribute {name!r}")
