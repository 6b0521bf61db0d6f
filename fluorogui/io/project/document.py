"""Project files (``.fluoro``): one JSON document holding a ``fluorogui.core.records.Project``.

Layout (schema 6, the current one)::

    {"format": "fluorogui-project", "schema_version": 6, "app_version": "...",
     "views": [View.to_dict(), ...],
     "sequences": [{"paths": ["cam1/0001.tif", ...]}, ...],      # one per view
                  # a view with fewer images than frames adds "frames_without_image": [40, ...]
     "frames": [0, 20, ...],
     "models": [{"component": "femur", "mesh_path": "...", "point_density": 15000,
                 "local_frame": 4x4}],
     "records": [{"frame": 0, "view": 0, "component": "femur", "points": <Kx2>,
                  "spline": {"knots": <n+4>, "coefficients": <2xn>, "degree": 3,
                             "t_range": [t0, t1]} or null, "reviewed": true,
                  "weights": <K>}],            # weights: optional, each point's in a match
     "poses": [{"frame": 0, "component": "femur", "pose": [x, y, z, a, b, g],
                "match": {"objective_mm": ..., ..., "quality": {...}, "history": [...]} or null,
                                                             # quality, history: optional
                "reviewed": false, "status": "matched", "reason": ""}],
     "settings": {...}}

``<...>`` arrays are written packed (``{"dtype": "<f8", "shape": [...], "base64": ...}``,
exact float64) and read packed or as nested lists (schemas 1-3); small arrays are lists.
A file is checked once against ``schema.ProjectDocument`` (types, ranges, counts, the
frames / views / components referred to, rigid local frames, no NUL in a path, no key twice
in an object) and ``io.plausible`` (views a fluoroscope can have); any problem is one
InputError naming the file and the field. Records and poses are counted against what the
frames can hold before any of them is checked, then checked one by one as they are
converted, each raw item dropped once converted (the JSON, its checked form and the
project are never all held at once). File paths are stored relative to the project file's
folder (with "/" separators) and made absolute on load; the files they name need not
exist. Older schemas are upgraded step by step through ``MIGRATIONS``; newer ones are
refused. Saving is atomic (``files.atomic_write_text``) and keeps the previous file as
``<name>.fluoro.bak``.
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np
from pydantic import ValidationError

from fluorogui import __version__
from fluorogui.core.projection.geometry import GeometryError, View
from fluorogui.core.records import (
    ImageSequence,
    MatchRecord,
    ModelEntry,
    OutlineRecord,
    PoseRecord,
    Project,
    SplineRecord,
)
from fluorogui.io.errors import InputError, warn_input
from fluorogui.io.files import atomic_write_text, clean_stale_temps, read_input_bytes
from fluorogui.io.plausible import view_problem
from fluorogui.io.project import journal
from fluorogui.io.schema import (
    DocumentError,
    PoseDocument,
    ProjectDocument,
    RecordDocument,
    describe,
    item_problem,
    pack_array,
    parse_json,
)
from fluorogui.logs import log_exception

PROJECT_FORMAT = "fluorogui-project"
PROJECT_SUFFIX = ".fluoro"
SCHEMA_VERSION = 6
MAX_PROJECT_BYTES = 1 << 30  # 1 GiB


class _Malformed(Exception):
    """A problem inside the document; becomes an InputError naming the file."""


# -- migrations -----------------------------------------------------------------------------------
def migrate_1_to_2(document: dict) -> dict:
    """Schema 1 stored outlines as ``"outlines": [{"key": "frame/view/component", ...}]`` and
    had no ``settings``; schema 2 stores ``records`` with separate key fields."""
    records = []
    for i, outline in enumerate(_get(document, "outlines", "", list)):
        where = f"outlines[{i}]"
        if not isinstance(outline, dict):
            raise _Malformed(f"'{where}' must be an object")
        parts = str(_get(outline, "key", where, str)).split("/", 2)
        if len(parts) != 3:
            raise _Malformed(f"'{where}.key' must read 'frame/view/component'")
        try:
            frame, view = int(parts[0]), int(parts[1])
        except ValueError:
            raise _Malformed(f"'{where}.key' must start with two whole numbers") from None
        record = {k: v for k, v in outline.items() if k != "key"}
        records.append({"frame": frame, "view": view, "component": parts[2], **record})
    upgraded = {k: v for k, v in document.items() if k != "outlines"}
    upgraded["records"] = records
    upgraded["settings"] = {}
    return upgraded


def migrate_2_to_3(document: dict) -> dict:
    """Schema 3 gives every pose a ``status`` (matched / needs_review / failed / placed) and
    a ``reason``: a converged match was shown as matched, anything else was not."""
    upgraded = dict(document)
    poses = []
    for i, raw in enumerate(_get(document, "poses", "", list)):
        raw = dict(_object(raw, f"poses[{i}]"))
        match = raw.get("match")
        converged = isinstance(match, dict) and match.get("converged") is True
        raw["status"] = "placed" if match is None else ("matched" if converged else "needs_review")
        raw["reason"] = "" if match is None or converged else "the match did not converge"
        poses.append(raw)
    upgraded["poses"] = poses
    return upgraded


def migrate_3_to_4(document: dict) -> dict:
    """Schema 4 may store outline points and spline arrays packed (``schema.pack_array``);
    the nested lists of schema 3 are still read as they are, so nothing changes."""
    return dict(document)


def migrate_4_to_5(document: dict) -> dict:
    """Schema 5 stores the loop's rim refinement as "auto", "on" or "off"
    (``LoopSettings.rim``); schema 4 stored true or false, false being the default then,
    which is "auto" now."""
    upgraded = dict(document)
    settings = upgraded.get("settings")
    loop = settings.get("workflow", {}).get("loop") if isinstance(settings, dict) else None
    if isinstance(loop, dict) and isinstance(loop.get("rim"), bool):
        workflow = dict(settings["workflow"], loop=dict(loop, rim="on" if loop["rim"] else "auto"))
        upgraded["settings"] = dict(settings, workflow=workflow)
    return upgraded


def migrate_5_to_6(document: dict) -> dict:
    """Schema 6 makes a view with fewer images than the project has frames say so
    (``frames_without_image``: the frames past its last image); schema 5 allowed such a
    sequence silently (``fluorogui import`` writes one for a shorter camera). The loader
    warns about the frames this states."""
    upgraded = dict(document)
    frames, sequences = document.get("frames"), document.get("sequences")
    if isinstance(frames, list) and isinstance(sequences, list):
        stated = []
        for sequence in sequences:
            paths = sequence.get("paths") if isinstance(sequence, dict) else None
            if isinstance(paths, list) and len(paths) < len(frames) and "frames_without_image" not in sequence:
                sequence = dict(sequence, frames_without_image=frames[len(paths):])
            stated.append(sequence)
        upgraded["sequences"] = stated
    return upgraded


MIGRATIONS = {1: migrate_1_to_2, 2: migrate_2_to_3, 3: migrate_3_to_4, 4: migrate_4_to_5, 5: migrate_5_to_6}


def upgrade(document: dict) -> dict:
    """Apply the migration chain to a document of any known older schema; the input is left
    as it is (each migration returns new containers for what it changes)."""
    version = document["schema_version"]
    document = dict(document)  # migrations build new containers; they never change the input
    while version < SCHEMA_VERSION:
        if version not in MIGRATIONS:
            raise _Malformed(f"cannot upgrade schema {version}: no migration known")
        try:
            document = MIGRATIONS[version](document)
        except _Malformed as exc:
            raise _Malformed(f"cannot upgrade from schema {version}: {exc}") from None
        version += 1
        document["schema_version"] = version
    return document


# -- public API -----------------------------------------------------------------------------------
def load_project(path) -> Project:
    """Read a ``.fluoro`` project file; paths in it are resolved against its folder.

    Every problem, whatever the file holds, is one InputError naming the file and the field;
    what was repaired (an older schema's view with fewer images than frames) is an
    InputWarning."""
    path = Path(path)
    raw = read_input_bytes(path, "project file", MAX_PROJECT_BYTES)
    clean_stale_temps(path)
    stamp = journal.stamp_of(raw)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise InputError(path, "not a fluorogui project (not a text file)") from None
    del raw  # the text, then the parsed document, then the project: never all three at once
    try:
        try:
            document = parse_json(text)
        except DocumentError as exc:
            raise InputError(path, str(exc)) from None
        del text
        if isinstance(document, dict):
            journal.merge(document, path, stamp)  # frames a run stored since the last full save
        return _project_from_parsed(document, path)
    except InputError:
        raise
    except (RecursionError, ValueError, OverflowError, TypeError, KeyError, IndexError, AttributeError,
            MemoryError) as exc:  # a check we lack: refuse the file, keep the traceback in the log
        log_exception(f"unexpected problem in project {path}")
        raise InputError(path, f"malformed project file ({type(exc).__name__})") from None


def _project_from_parsed(document: Any, path: Path) -> Project:
    if not isinstance(document, dict) or document.get("format") != PROJECT_FORMAT:
        raise InputError(path, "not a fluorogui project")
    version = document.get("schema_version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise InputError(path, f"not a fluorogui project (unknown schema version {version!r})")
    if version > SCHEMA_VERSION:
        raise InputError(
            path,
            f"written by a newer fluorogui (schema {version} > {SCHEMA_VERSION}); update fluorogui to open it",
        )
    try:
        project = project_from_document(upgrade(document), path.parent.absolute(), consume=True)
    except _Malformed as exc:
        raise InputError(path, str(exc)) from None
    if version < 6:
        for k, sequence in enumerate(project.sequences):
            short = project.frames[len(sequence.paths):]
            if short:
                frames = f"frame {short[0]}" if len(short) == 1 else f"frames {short[0]} to {short[-1]}"
                warn_input(path, f"view {k + 1} has {len(sequence.paths)} of the {len(project.frames)} frames' images "
                                 f"(schema {version} allowed it silently): {frames} will be flagged when matched; "
                                 f"saving states this in the file (sequences[{k}].frames_without_image)")
    return project


def save_project(project: Project, path) -> None:
    """Write ``project`` to ``path`` atomically, keeping the previous file as ``.bak``."""
    path = Path(path)
    document = project_to_document(project, path.parent.absolute())
    try:
        text = _compact_json(document)
    except ValueError:
        raise InputError(path, "cannot save: the project contains NaN or infinite numbers") from None
    except TypeError as exc:
        raise InputError(path, f"cannot save: a setting is not plain JSON data ({exc})") from None
    atomic_write_text(path, text + "\n", backup=True)
    journal.discard(path)  # what it held is in the file now


def journal_frames(project: Project, path, poses, records, *, settings: bool = False) -> None:
    """Append to the journal of the project file ``path`` the pose records ``poses`` and
    outline records ``records`` (keys) as the file would hold them, and the settings when
    ``settings`` (see ``io.project.journal``): a frame stored without rewriting the project."""
    path = Path(path)
    base = path.parent.absolute()
    entry = {"stamp": _stamp_of_file(path),
             "records": [_record_entry(key, project.records[key], base) for key in records if key in project.records],
             "poses": [_pose_entry(key, project.poses[key]) for key in poses if key in project.poses]}
    if settings:
        entry["settings"] = project.settings
    try:
        journal.append(path, entry)
    except ValueError:
        raise InputError(path, "cannot save: the project contains NaN or infinite numbers") from None


_STAMPS: dict = {}  # path -> (size, mtime_ns, stamp) of project files journaled over


def _stamp_of_file(path: Path) -> str:
    info = path.stat()
    known = _STAMPS.get(path)
    if known is None or known[:2] != (info.st_size, info.st_mtime_ns):
        known = _STAMPS[path] = (info.st_size, info.st_mtime_ns, journal.stamp_of(path.read_bytes()))
    return known[2]


def _compact_json(document: dict) -> str:
    """The document as JSON with one top-level field, record or pose per line and no
    whitespace inside them: readable in a text editor, and several times smaller (and
    faster to write after every tracked frame) than indented JSON."""
    def dumps(value) -> str:
        return json.dumps(value, separators=(",", ":"), allow_nan=False)

    lines = []
    for key, value in document.items():
        if isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            items = ",\n  ".join(dumps(v) for v in value)
            lines.append(f"{json.dumps(key)}: [\n  {items}\n ]")
        else:
            lines.append(f"{json.dumps(key)}: {dumps(value)}")
    return "{\n " + ",\n ".join(lines) + "\n}"


# -- Project -> document --------------------------------------------------------------------------
def project_to_document(project: Project, base: Path) -> dict:
    """The current-schema JSON document of a project, paths relative to ``base``."""
    return {
        "format": PROJECT_FORMAT,
        "schema_version": SCHEMA_VERSION,
        "app_version": __version__,
        "views": [view.to_dict() for view in project.views],
        "sequences": [{"paths": [_relative(p, base) for p in seq.paths]}
                      | ({"frames_without_image": [int(f) for f in project.frames[len(seq.paths):]]}
                         if len(seq.paths) < len(project.frames) else {})
                      for seq in project.sequences],
        "frames": [int(f) for f in project.frames],
        "models": [
            {
                "component": m.component,
                "mesh_path": _relative(m.mesh_path, base),
                "point_density": int(m.point_density),
                "local_frame": m.local_frame.tolist(),
            }
            for m in project.models
        ],
        "records": [_record_entry(key, record, base) for key, record in sorted(project.records.items(), key=_sort_key)],
        "poses": [_pose_entry(key, record) for key, record in sorted(project.poses.items(), key=_sort_key)],
        "settings": project.settings,
    }


def _record_entry(key, record: OutlineRecord, base: Path) -> dict:
    frame, view, component = key
    return {
        "frame": int(frame),
        "view": int(view),
        "component": component,
        "points": pack_array(record.points),
        "spline": None if record.spline is None else _spline_to_dict(record.spline),
        "reviewed": bool(record.reviewed),
    } | ({} if record.weights is None else {"weights": pack_array(record.weights)})


def _pose_entry(key, record: PoseRecord) -> dict:
    frame, component = key
    return {
        "frame": int(frame),
        "component": component,
        "pose": record.pose.tolist(),
        "match": None if record.match is None else _match_to_dict(record.match),
        "reviewed": bool(record.reviewed),
        "status": str(record.status),
        "reason": record.reason,
    }


def _sort_key(item):
    return tuple(str(k) if isinstance(k, str) else f"{int(k):012d}" for k in item[0])


def _spline_to_dict(spline: SplineRecord) -> dict:
    return {
        "knots": pack_array(spline.knots),
        "coefficients": pack_array(spline.coefficients),
        "degree": spline.degree,
        "t_range": list(spline.t_range),
    }


def _match_to_dict(match: MatchRecord) -> dict:
    return {
        "objective_mm": float(match.objective_mm),
        "per_view_mean_mm": [float(v) for v in match.per_view_mean_mm],
        "calls": int(match.calls),
        "seconds": float(match.seconds),
        "converged": bool(match.converged),
        "method": str(match.method),
        "settings": match.settings,
        "quality": match.quality,
        "history": [float(v) for v in match.history],
    }


def _relative(p: Path, base: Path) -> str:
    p = Path(p)
    if not p.is_absolute():
        return PurePosixPath(*p.parts).as_posix() if p.parts else "."
    try:
        return Path(os.path.relpath(p, base)).as_posix()
    except ValueError:  # another drive on Windows: keep it absolute
        return p.as_posix()


# -- document -> Project --------------------------------------------------------------------------
def project_from_document(document: dict, base: Path, consume: bool = False) -> Project:
    """A Project from a current-schema document (checked against ``ProjectDocument`` and its
    invariants); relative paths are joined to ``base``. Raises _Malformed naming the field.
    With ``consume`` the document's records and poses are emptied as they are converted,
    which keeps a large project's memory near that of its JSON."""
    try:
        doc = ProjectDocument.model_validate(document)
    except ValidationError as exc:
        raise _Malformed(describe(exc)) from None
    _check_settings(doc)
    views = []
    for i, raw in enumerate(doc.views):
        try:
            view = View.from_dict(raw.model_dump())
        except GeometryError as exc:
            raise _Malformed(f"'views[{i}]': {exc}") from None
        problem = view_problem(view)
        if problem:
            kind, sentence = problem
            raise _Malformed(f"views[{i}].{_VIEW_FIELDS[kind]}: {sentence}")
        views.append(view)
    frames, components = set(doc.frames), [m.component for m in doc.models]
    records = {}
    for i, raw in _items(doc.records, consume):
        item = _checked(RecordDocument, raw, "records", i, frames=frames, components=components, views=len(views))
        key = (item.frame, item.view, item.component)
        if key in records:
            raise _Malformed(f"'records[{i}]' repeats the outline of frame {key[0]}, view {key[1]}, {key[2]}")
        spline = item.spline
        records[key] = OutlineRecord(
            points=item.points,
            spline=None if spline is None else SplineRecord(spline.knots, spline.coefficients,
                                                            spline.degree, tuple(spline.t_range)),
            reviewed=item.reviewed,
            weights=item.weights,
        )
    poses = {}
    for i, raw in _items(doc.poses, consume):
        item = _checked(PoseDocument, raw, "poses", i, frames=frames, components=components, views=len(views))
        key = (item.frame, item.component)
        if key in poses:
            raise _Malformed(f"'poses[{i}]' repeats the pose of frame {key[0]}, {key[1]}")
        if item.match is not None and not _all_finite(item.match.settings | item.match.quality):
            raise _Malformed(f"'poses[{i}].match' holds a number too large to be finite")
        poses[key] = PoseRecord(
            pose=np.array(item.pose, dtype=float),
            match=None if item.match is None else MatchRecord(**(item.match.model_dump() | {
                "history": [float(v) for v in item.match.history]})),
            reviewed=item.reviewed,
            status=item.status,
            reason=item.reason,
        )
    return Project(
        views=views,
        sequences=[ImageSequence([_absolute(p, base) for p in seq.paths]) for seq in doc.sequences],
        frames=list(doc.frames),
        models=[ModelEntry(m.component, _absolute(m.mesh_path, base), m.point_density, np.array(m.local_frame))
                for m in doc.models],
        records=records,
        poses=poses,
        settings=document["settings"],
    )


#: a view's field in a project file for each kind of ``plausible.view_problem``
_VIEW_FIELDS = {"size": "image_size_px", "focal": "distance_mm", "pitch": "pitch_mm", "distance": "distance_mm",
                "principal": "principal_point_px", "source": "source_mm"}


def _items(items: list, consume: bool):
    """``enumerate(items)``; with ``consume`` each item is dropped from the list once taken."""
    for i in range(len(items)):
        item = items[i]
        if consume:
            items[i] = None
        yield i, item


def _checked(model, raw, kind: str, index: int, *, frames: set, components: list, views: int):
    """One record or pose checked by its schema and against its project."""
    try:
        item = model.model_validate(raw)
    except ValidationError as exc:
        raise _Malformed(describe(exc, f"{kind}[{index}]")) from None
    problem = item_problem(kind, index, item, frames, components=components, views=views)
    if problem:
        raise _Malformed(problem)
    return item


def _check_settings(doc: ProjectDocument) -> None:
    """The settings: finite, and every registered section (``core.settings.SECTIONS``) of a
    kind its owner can use."""
    from fluorogui.core.settings import check_sections  # the engine's settings records: loaded when needed

    if not _all_finite(doc.settings):
        raise _Malformed("'settings' holds a number too large to be finite")
    try:
        check_sections(doc.settings)
    except ValueError as exc:
        raise _Malformed(str(exc)) from None


def _all_finite(value) -> bool:
    """No infinite float (1e999 in the file) anywhere in free-form JSON data."""
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, dict):
        return all(_all_finite(v) for v in value.values())
    if isinstance(value, list):
        return all(_all_finite(v) for v in value)
    return True


def _absolute(text: str, base: Path) -> Path:
    p = Path(text)
    return p if p.is_absolute() else Path(os.path.normpath(base / p))


# -- field checks ---------------------------------------------------------------------------------
_MISSING = object()
_TYPE_NAMES = {list: "a list", dict: "an object", str: "a text", bool: "true or false"}


def _get(container: dict, key: str, where: str, kind=None):
    name = f"{where}.{key}" if where else key
    value = container.get(key, _MISSING)
    if value is _MISSING:
        raise _Malformed(f"missing the field '{name}'")
    if kind is not None and not isinstance(value, kind):
        raise _Malformed(f"field '{name}' must be {_TYPE_NAMES.get(kind, kind.__name__)}")
    return value


def _object(value, where: str) -> dict:
    if not isinstance(value, dict):
        raise _Malformed(f"'{where}' must be an object")
    return value
