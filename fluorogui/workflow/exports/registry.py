"""The export formats, each declared once: a format module in ``exports.formats`` registers
an ``ExportFormat`` (its name, option, label, default file name, whether it needs a frame
rate or the knee rows, and its writer), and the command line's options, the app's export
dialog and the docs' format table are made from the registry.

``write_exports`` writes any set of them with one ``ExportOptions`` (the knee rows computed
once), and ``export_notes`` says what the files left out and why, in one wording for the
command line and the app (each names the formats and the remedy its own way).
"""
from __future__ import annotations

import importlib
import pkgutil
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Mapping

from fluorogui.io.files import check_output_file, check_output_folder


@dataclass(frozen=True)
class ExportOptions:
    """What every writer may use: the frame rate for this export (None: the project's),
    whether poses not matched or accepted go in, the view of a camera-frame export (0-based),
    the x axis of a figure, and the knee rows (computed once for all files; None: on demand)."""

    fps: float | None = None
    include_unreviewed: bool = False
    view: int | None = None
    against: str = "frame"
    rows: list | None = None
    #: the values of the formats' own options (``FormatOption.dest`` -> value; absent: default)
    extra: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class FormatOption:
    """An option of one format (the command line's ``flag``; the app uses its default).
    ``parse(text)`` turns the text into its value, raising ValueError with the problem."""

    flag: str
    dest: str
    help: str
    metavar: str = ""
    parse: Callable[[str], Any] = str
    default: Any = None


@dataclass(frozen=True)
class ExportFormat:
    """One export format. ``write(session, path, options) -> [paths written]``."""

    name: str  #: the key: the command line's ``--name``, the dialog's check box
    label: str  #: the dialog's words for it
    default_name: str  #: the dialog's file name, ``{stem}`` the project's
    metavar: str  #: the command line's placeholder (``OUT.csv``)
    help: str  #: the command line's help
    write: Callable = field(repr=False, compare=False)
    order: int = 100  #: where it is listed (the dialog, the options, the writing order)
    short: str = ""  #: how the app's messages name it (``.tra``)
    timed: bool = False  #: needs a frame rate (time = frame / fps)
    kinematic: bool = False  #: uses the knee rows (and so the knee's side)
    folder: bool = False  #: writes files into a folder, not one file
    needs_view: bool = False  #: written in one view's camera frame (``options.view``)
    view_label: str = ""  #: the dialog's words for that view's choice
    suffixes: tuple[str, ...] = ()  #: the file suffixes it can write (empty: any)
    suffix_problem: str = ""  #: what to say of another suffix
    statusless: bool = False  #: no status column: poses flagged for review are left out unless included
    motion: bool = False  #: a motion file: poses not matched or accepted are left out unless included
    checked: bool = False  #: ticked in the dialog by default
    #: its own options (the command line's; shared flags are declared once)
    options: tuple[FormatOption, ...] = ()
    #: ``caveat(session) -> str``: a warning about this session's file ("" when none)
    caveat: Callable | None = field(default=None, repr=False, compare=False)

    def wrong_suffix(self, path) -> str:
        """What is wrong with ``path``'s suffix for this format ("" when nothing)."""
        if self.suffixes and Path(path).suffix.lower() not in self.suffixes:
            return self.suffix_problem or f"the file must be {_either(self.suffixes)}"
        return ""

    def check_target(self, path) -> Path:
        """The output path, checked before any work (InputError naming it)."""
        return check_output_folder(path) if self.folder else check_output_file(path)


_REGISTRY: dict[str, ExportFormat] = {}
_LOADED = False


def register(fmt: ExportFormat) -> ExportFormat:
    """Add a format (a format module calls this when imported). Its name is the command
    line's option and a Python name (``--c3d``, ``args.c3d``)."""
    if not fmt.name.isidentifier() or fmt.name.startswith("_"):
        raise ValueError(f"an export format's name must be a word (letters, digits, _): {fmt.name!r}")
    if fmt.name in _REGISTRY and _REGISTRY[fmt.name] is not fmt:
        raise ValueError(f"two export formats are named {fmt.name!r}")
    taken = {o.flag for f in _REGISTRY.values() if f.name != fmt.name for o in f.options}
    if clash := [o.flag for o in fmt.options if o.flag in taken]:
        raise ValueError(f"export format {fmt.name!r}: option {clash[0]} is another format's")
    _REGISTRY[fmt.name] = fmt
    return fmt


def formats() -> list[ExportFormat]:
    """Every registered format, in order; the modules of ``exports.formats`` are imported
    (and so registered) the first time."""
    global _LOADED
    if not _LOADED:
        package = importlib.import_module("fluorogui.workflow.exports.formats")
        for module in pkgutil.iter_modules(package.__path__):
            importlib.import_module(f"{package.__name__}.{module.name}")
        _LOADED = True
    return sorted(_REGISTRY.values(), key=lambda f: (f.order, f.name))


def format_named(name: str) -> ExportFormat:
    for fmt in formats():
        if fmt.name == name:
            return fmt
    raise KeyError(f"no export format {name!r} (known: {', '.join(f.name for f in formats())})")


def write_exports(session, targets: dict[str, Path], options: ExportOptions | None = None) -> list[Path]:
    """Write ``targets`` (format name -> path) in the registry's order; the knee rows are
    computed once when a format needs them and ``options`` has none. Returns every file
    written. Raises InputError naming a file that cannot be written or needs a frame rate."""
    options = options or ExportOptions()
    chosen = [f for f in formats() if f.name in targets]
    if options.rows is None and any(f.kinematic for f in chosen):
        options = replace(options, rows=session.knee_rows())
    written: list[Path] = []
    for fmt in chosen:
        written += fmt.write(session, targets[fmt.name], options)
    return written


def export_notes(session, names, options: ExportOptions, naming: Callable[[ExportFormat], str],
                 *, remedy: str) -> list[tuple[list, str]]:
    """What the exports ``names`` leave out, or write although unchecked, each as (poses or
    frames concerned, the words): poses flagged for review in the files without a status,
    poses not matched or accepted in the motion files, and each format's own caveat (a C3D
    of non-consecutive frame numbers). ``naming`` gives a format's name in the words (``--tra`` / ``.tra``), ``remedy``
    how to include the left-out poses (the app's key, the command line's option)."""
    from fluorogui.workflow.exports.tables import left_out_of_motion_files, unreviewed_matches

    chosen = [f for f in formats() if f.name in set(names)]
    notes = []
    statusless = [f for f in chosen if f.statusless]
    if statusless and (flagged := unreviewed_matches(session)):
        where = "/".join(naming(f) for f in statusless)
        notes.append((flagged, "written although flagged for review" if options.include_unreviewed else
                      f"flagged for review and left out of {where} as NaN ({remedy})"))
    motion = [f for f in chosen if f.motion]
    if motion and (left := left_out_of_motion_files(session)):
        where = "/".join(naming(f) for f in motion)
        notes.append((left, "written although not matched or accepted" if options.include_unreviewed else
                      f"placed by hand or flagged for review and not accepted, left out of {where} "
                      f"(invalid markers, NaN values; {remedy})"))
    notes += [([], words) for f in chosen if f.caveat is not None and (words := f.caveat(session))]
    return notes


def _either(items) -> str:
    items = list(items)
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " or " + items[-1]
