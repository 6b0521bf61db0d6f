"""The schemas of fluorogui's own file formats, checked once at the boundary (pydantic v2).

* ``ProjectDocument``: a ``.fluoro`` project of the current schema (``io.project.document``);
* ``CalibrationDocument``: a fluorogui calibration JSON (``io.calibration``);

Every model is strict: numbers must be JSON numbers (``"12"`` is refused), finite, and in
a stated range; lists have bounded lengths. Large arrays (outline points, spline knots and
coefficients, objective histories) are nested lists or, since project schema 4, packed
binary (``pack_array``), and are checked with numpy. Cross-field invariants (counts agree, the
frames, views and components referred to exist) are model validators. ``parse_json`` reads
a document with limits on nesting, integer digits and NaN/Infinity before anything else
sees it, and ``describe`` turns a pydantic ``ValidationError`` into one line naming the
field. Nothing here knows about paths on disk: ``io.project`` converts.
"""
from __future__ import annotations

import base64
import json
import math
from typing import Annotated, Any, Literal, NamedTuple, Optional

import numpy as np
from pydantic import AfterValidator, BaseModel, BeforeValidator, ConfigDict, Field, ValidationError, model_validator

from fluorogui.core.status import Status
from fluorogui.io.plausible import rigid_problem

MAX_NESTING = 64  # a project is 6 deep; a file nested deeper is not ours
MAX_JSON_ITEMS = 10_000_000  # a 100 MB project of small outlines holds some 7 million
MAX_OBJECT_MEMBERS = 100_000  # fluorogui writes objects of at most a few hundred members
MAX_INTEGER_DIGITS = 30
MAX_VIEWS = 16
MAX_FRAMES = 1_000_000
MAX_OUTLINE_POINTS = 100_000  # a traced outline has hundreds to thousands
MAX_TEXT = 4096  # names, paths, reasons
POSE_STATUSES = tuple(s.value for s in Status)


class DocumentError(ValueError):
    """A document that is not valid JSON within our limits; the message says why."""


# -- reading JSON within limits -----------------------------------------------------------------
_STRUCTURAL = np.zeros(256, dtype=bool)
_STRUCTURAL[[44, 91, 93, 123, 125]] = True  # , [ ] { }
_STEP = np.zeros(256, dtype=np.int8)
_STEP[[91, 123]], _STEP[[93, 125]] = 1, -1
_BLOCK = 1 << 22


class JsonShape(NamedTuple):
    depth: int  # the deepest nesting of objects and lists
    items: int  # objects, lists and the commas between values
    widest_object: int  # the most members (commas + 1) of one object


def json_structure(text: str) -> JsonShape:
    """The shape of JSON ``text`` (brackets and commas inside strings not counted), found
    before ``json.loads`` allocates anything: vectorised (numpy over the bracket, comma and
    quote positions only) and read in blocks of 4 MB: for 100 MB of text, whatever it holds,
    a few seconds and under 200 MB."""
    raw = text.encode("utf-8", "surrogatepass")
    depth = deepest = items = widest = 0
    inside = False  # within a string at the start of the block
    backslashes = 0  # the run of backslashes that ended the previous block
    open_kind = np.zeros(MAX_NESTING + 2, dtype=np.uint8)  # per level: the container open there, its commas
    open_commas = np.zeros(MAX_NESTING + 2, dtype=np.int64)
    for start in range(0, len(raw), _BLOCK):
        data = np.frombuffer(raw, dtype=np.uint8, count=min(_BLOCK, len(raw) - start), offset=start)
        quotes = np.flatnonzero(data == 34)
        before = np.where(quotes > 0, data[np.maximum(quotes - 1, 0)], 92 if backslashes else 0)
        escaped = quotes[before == 92]
        if escaped.size:  # a quote after an odd run of backslashes is part of the string (rare)
            keep = np.ones(quotes.size, dtype=bool)
            for at in escaped:
                run = 0
                while at - 1 - run >= 0 and data[at - 1 - run] == 92:
                    run += 1
                run += backslashes if run == at else 0
                keep[np.searchsorted(quotes, at)] = run % 2 == 0
            quotes = quotes[keep]
        marks = np.flatnonzero(_STRUCTURAL[data])
        marks = marks[(np.searchsorted(quotes, marks) + inside) % 2 == 0]  # outside strings
        if marks.size:
            kinds = data[marks]
            steps = _STEP[kinds]
            items += int(np.count_nonzero(steps >= 0))
            levels = np.cumsum(steps, dtype=np.int64) + depth
            deepest, depth = max(deepest, int(levels.max())), int(levels[-1])
            if deepest > MAX_NESTING:
                break  # refused for its depth; the levels below would not fit the arrays
            widest = max(widest, _widest_object(kinds, levels, open_kind, open_commas))
        inside = (inside + quotes.size) % 2 == 1
        tail = data[::-1]
        run = int(np.argmax(tail != 92)) if np.any(tail != 92) else data.size
        backslashes = run + (backslashes if run == data.size else 0)
    return JsonShape(deepest, items, widest)


def _widest_object(kinds, levels, open_kind, open_commas) -> int:
    """The most members of an object among the containers seen in this block; ``open_kind``
    and ``open_commas`` carry the container open at each level from block to block."""
    commas = np.flatnonzero(kinds == 44)
    opens = np.flatnonzero((kinds == 91) | (kinds == 123))
    widest = 0
    for level in np.unique(np.r_[levels[commas], levels[opens]]):
        if not 0 <= level < open_kind.size:
            continue  # unbalanced: refused by the parser
        at_level = opens[levels[opens] == level]
        owner = np.searchsorted(at_level, commas[levels[commas] == level]) - 1  # -1: the carried container
        counts = np.bincount(owner + 1, minlength=at_level.size + 1)
        counts[0] += open_commas[level]
        is_object = np.r_[open_kind[level] == 123, kinds[at_level] == 123]
        if np.any(is_object):
            widest = max(widest, int(counts[is_object].max()) + 1)
        if at_level.size:
            open_kind[level] = kinds[at_level[-1]]
        open_commas[level] = counts[-1]
    return widest


def nesting_depth(text: str, limit: int = MAX_NESTING) -> int:
    """The deepest nesting of ``[`` / ``{`` in JSON ``text``, brackets inside strings not counted."""
    return json_structure(text).depth


def _parse_int(text: str) -> int:
    if len(text.lstrip("-")) > MAX_INTEGER_DIGITS:
        raise DocumentError(f"a whole number with {len(text)} digits")
    return int(text)


def _parse_constant(text: str):
    raise DocumentError(f"{text} is not a number JSON allows")


def _unique_keys(pairs: list) -> dict:
    """An object's pairs as a dict; DocumentError when a key is given twice (plain JSON would
    keep the last one silently, so two values of one field could disagree unseen)."""
    document = dict(pairs)
    if len(document) != len(pairs):
        seen = set()
        for key, _ in pairs:
            if key in seen:
                raise DocumentError(f"the key {key[:40]!r} appears twice in one object")
            seen.add(key)
    return document


def parse_json(text: str, limit: int = MAX_NESTING, most_items: int = MAX_JSON_ITEMS) -> Any:
    """JSON ``text`` as Python data; DocumentError when it is malformed, nested more than
    ``limit`` deep, holds more than ``most_items`` objects, lists and values or an object of
    more than ``MAX_OBJECT_MEMBERS`` (checked before anything is allocated: each value costs
    some 50-150 bytes in memory), NaN, Infinity, huge integers or a key twice in one object.
    A number too large for a float (1e999) reads as inf, which the schema's finite checks
    refuse where it is."""
    shape = json_structure(text)
    if shape.depth > limit:
        raise DocumentError(f"nested more than {limit} levels deep")
    if shape.items > most_items:
        raise DocumentError(f"holds {shape.items:,} JSON values, more than the {most_items:,} fluorogui reads "
                            "(some 1.5 GB in memory)")
    if shape.widest_object > MAX_OBJECT_MEMBERS:
        raise DocumentError(f"an object has {shape.widest_object:,} members; fluorogui's have at most a few "
                            f"hundred (at most {MAX_OBJECT_MEMBERS:,} are read)")
    try:
        return json.loads(text, parse_int=_parse_int, parse_constant=_parse_constant,
                          object_pairs_hook=_unique_keys)
    except DocumentError:
        raise
    except (ValueError, RecursionError):  # JSONDecodeError is a ValueError
        raise DocumentError("file is truncated or not valid JSON") from None


_KINDS = {
    "float_type": "a number", "int_type": "a whole number", "int_from_float": "a whole number",
    "finite_number": "a finite number", "bool_type": "true or false", "string_type": "a text",
    "dict_type": "an object", "model_type": "an object", "model_attributes_type": "an object",
    "list_type": "a list", "none_required": "null",
}
_LIMITS = {"greater_than": ">", "greater_than_equal": ">=", "less_than": "<", "less_than_equal": "<="}


def _shown(value) -> str:
    if isinstance(value, (dict, list)):
        return "an object" if isinstance(value, dict) else f"a list of {len(value)}"
    return repr(value)[:40]


def describe(error: ValidationError, prefix: str = "") -> str:
    """The first problem of a ValidationError as ``field 'a.b[2]' must be ...``, in plain words."""
    first = error.errors(include_url=False)[0]
    where = prefix
    for part in first["loc"]:
        if isinstance(part, int):
            where += f"[{part}]"
        elif str(part) and not str(part).startswith("function-"):
            where += f".{part}" if where else str(part)
    kind, ctx, value = first["type"], first.get("ctx", {}), first.get("input")
    field = f"field '{where}'" if where else "the document"
    if kind == "missing":
        return f"missing the field '{where}'"
    if kind in _KINDS:
        return f"{field} must be {_KINDS[kind]}, not {_shown(value)}"
    if kind in _LIMITS:
        limit = next(iter(ctx.values()), "?")
        return f"{field} must be {_LIMITS[kind]} {limit}, not {_shown(value)}"
    if kind == "too_short":
        return f"{field} has {ctx.get('actual_length', '?')} values, fewer than the {ctx.get('min_length')} it needs"
    if kind == "too_long":
        return f"{field} has {ctx.get('actual_length', '?')} values, more than the {ctx.get('max_length')} allowed"
    if kind == "string_too_long":
        return f"{field} is longer than {ctx.get('max_length')} characters"
    if kind == "string_too_short":
        return f"{field} must not be empty"
    if kind == "literal_error":
        return f"{field} must be {ctx.get('expected', '?')}, not {_shown(value)}"
    message = first["msg"].removeprefix("Value error, ")
    return f"field '{where}': {message}" if where else message


# -- field types ------------------------------------------------------------------------------
Finite = Annotated[float, Field(allow_inf_nan=False)]
NonNegative = Annotated[float, Field(allow_inf_nan=False, ge=0)]
Positive = Annotated[float, Field(allow_inf_nan=False, gt=0)]
Coordinate = Annotated[float, Field(allow_inf_nan=False, ge=-1e7, le=1e7)]  # mm or px
Count = Annotated[int, Field(ge=0, le=10**12)]
FrameNumber = Annotated[int, Field(ge=0, le=10**9)]
Text = Annotated[str, Field(max_length=MAX_TEXT)]
Name = Annotated[str, Field(min_length=1, max_length=200)]


def fixed(n: int, item=Finite):
    """A list of exactly ``n`` items."""
    return Annotated[list[item], Field(min_length=n, max_length=n)]


def bounded(item, most: int, least: int = 0):
    return Annotated[list[item], Field(min_length=least, max_length=most)]


# -- numeric arrays: nested lists (schema <= 3) or packed binary (schema 4) ---------------------
PACKED_DTYPE = "<f8"


def pack_array(array) -> dict:
    """A float64 array as ``{"dtype": "<f8", "shape": [...], "base64": "..."}``: exact, and
    several times smaller and faster to read than nested lists of numbers."""
    array = np.ascontiguousarray(array, dtype=PACKED_DTYPE)
    return {"dtype": PACKED_DTYPE, "shape": list(array.shape), "base64": base64.b64encode(array.tobytes()).decode()}


def _unpack(value: dict) -> np.ndarray:
    if set(value) != {"dtype", "shape", "base64"} or value["dtype"] != PACKED_DTYPE:
        raise ValueError(f"must be a list of numbers or a packed array ({PACKED_DTYPE})")
    shape, data = value["shape"], value["base64"]
    if not isinstance(shape, list) or not 1 <= len(shape) <= 2 or \
            not all(isinstance(n, int) and not isinstance(n, bool) and 0 <= n <= 10**7 for n in shape):
        raise ValueError("the packed array's shape must be one or two sizes")
    if not isinstance(data, str):
        raise ValueError("the packed array's data must be base64 text")
    try:
        raw = base64.b64decode(data, validate=True)
    except ValueError:
        raise ValueError("the packed array's data is not valid base64") from None
    if len(raw) != 8 * math.prod(shape):
        raise ValueError(f"the packed array holds {len(raw) // 8} numbers, not the {math.prod(shape)} of its shape")
    return np.frombuffer(raw, dtype=PACKED_DTYPE).reshape(shape).astype(np.float64)


def numeric_array(shape: tuple, least: int = 0, most: int = MAX_OUTLINE_POINTS, limit: float = 1e7):
    """A field holding an array of finite numbers of ``shape`` (None: any length from
    ``least`` to ``most``) with values within ``±limit``; nested lists or a packed array.
    Checked with numpy (fast on large outlines); text, booleans and nulls are refused."""
    wanted = "x".join("N" if n is None else str(n) for n in shape)

    def check(value) -> np.ndarray:
        if isinstance(value, dict):
            array = _unpack(value)
        else:
            try:
                array = np.asarray(value)
            except (ValueError, TypeError):
                raise ValueError(f"must be a regular {wanted} array of numbers") from None
            if array.size and array.dtype.kind not in "iuf":
                raise ValueError(f"must be a {wanted} array of numbers (not text, true/false or null)")
            array = array.astype(np.float64)
        if array.size == 0 and len(shape) == 2 and shape[1] is not None:
            array = array.reshape(0, shape[1])
        if array.ndim != len(shape) or any(n is not None and n != m for n, m in zip(shape, array.shape)):
            raise ValueError(f"must be a {wanted} array, got shape {'x'.join(map(str, array.shape))}")
        free = [m for n, m in zip(shape, array.shape) if n is None]
        if free and not least <= free[0] <= most:
            raise ValueError(f"has {free[0]} entries; {least} to {most} are allowed")
        if not np.all(np.isfinite(array)):
            raise ValueError("holds NaN or infinite numbers")
        if array.size and np.abs(array).max() > limit:
            raise ValueError(f"holds numbers beyond ±{limit:g}")
        return array

    return Annotated[Any, AfterValidator(check)]


class _Strict(BaseModel):
    model_config = ConfigDict(strict=True, extra="ignore", frozen=False)


# -- views / calibrations --------------------------------------------------------------------------
class ViewDocument(_Strict):
    """``View.to_dict()``; the geometry itself (unit, orthogonal axes) is checked by View."""

    name: Text = ""
    source_mm: fixed(3, Coordinate)
    normal: fixed(3)
    e_u: fixed(3)
    e_v: fixed(3)
    distance_mm: Annotated[float, Field(allow_inf_nan=False, gt=0, le=1e5)]
    pitch_mm: fixed(2, Annotated[float, Field(allow_inf_nan=False, gt=0, le=100)])
    principal_point_px: fixed(2, Coordinate)
    image_size_px: fixed(2, Annotated[int, Field(ge=1, le=100_000)])
    # an image-intensifier correction (fluorogui.core.calibration.distortion), checked by View.from_dict
    distortion: Optional[dict] = None

    def model_dump(self, **kwargs):  # no "distortion": None key for views without one
        out = super().model_dump(**kwargs)
        if out.get("distortion") is None:
            out.pop("distortion", None)
        return out


class CalibrationDocument(_Strict):
    format: Literal["fluorogui-calibration"]
    version: Annotated[int, Field(ge=1, le=10**6)]
    view: ViewDocument


# -- projects ---------------------------------------------------------------------------------
class SequenceDocument(_Strict):
    """One view's image files in frame order. A view may have fewer images than the project
    has frames (``fluorogui import`` allows a shorter camera, and its frames are flagged when
    matched); since schema 6 such a sequence says so: ``frames_without_image`` lists the
    frames past its last image."""

    paths: bounded(Text, MAX_FRAMES)
    frames_without_image: bounded(FrameNumber, MAX_FRAMES) = Field(default_factory=list)


class ModelDocument(_Strict):
    component: Name
    mesh_path: Text
    point_density: Annotated[int, Field(ge=10, le=10_000_000)]
    local_frame: fixed(4, fixed(4))


class SplineDocument(_Strict):
    knots: numeric_array((None,), least=2)
    coefficients: numeric_array((2, None), least=1)
    degree: Annotated[int, Field(ge=1, le=5)]
    t_range: fixed(2)

    @model_validator(mode="after")
    def _consistent(self):
        n = self.coefficients.shape[1]
        if len(self.knots) != n + self.degree + 1:
            raise ValueError(f"{len(self.knots)} knots do not fit {n} coefficients of degree {self.degree}")
        if not self.t_range[0] < self.t_range[1]:
            raise ValueError("t_range must increase")
        return self


class RecordDocument(_Strict):
    frame: FrameNumber
    view: Annotated[int, Field(ge=0, lt=MAX_VIEWS)]
    component: Name
    points: numeric_array((None, 2))
    spline: SplineDocument | None
    reviewed: bool
    weights: numeric_array((None,)) | None = None  # per point, in a match (positive)

    @model_validator(mode="after")
    def _weights_fit_the_points(self):
        if self.weights is not None:
            if len(self.weights) != len(self.points):
                raise ValueError(f"{len(self.weights)} weights for {len(self.points)} points")
            if not np.all(self.weights > 0):
                raise ValueError("weights must be positive")
        return self


MAX_FREE_FORM = 100_000  # values in one free-form section (settings, a match's settings); fluorogui writes ~100


def _small_free_form(value):
    """Refuse a free-form section (``settings``, a match's ``settings`` / ``quality``) of more
    than ``MAX_FREE_FORM`` values before pydantic copies it: fluorogui writes some hundred."""
    pending, seen = [value], 0
    while pending:
        item = pending.pop()
        if isinstance(item, dict):
            pending.extend(item.values())
            seen += len(item)
        elif isinstance(item, list):
            pending.extend(item)
            seen += len(item)
        if seen > MAX_FREE_FORM:
            raise ValueError(f"holds more than {MAX_FREE_FORM:,} values; fluorogui writes a few hundred")
    return value


FreeForm = Annotated[dict[str, Any], BeforeValidator(_small_free_form)]


class MatchDocument(_Strict):
    objective_mm: NonNegative
    per_view_mean_mm: bounded(NonNegative, MAX_VIEWS)
    calls: Count
    seconds: NonNegative
    converged: bool
    method: Text
    settings: FreeForm
    quality: FreeForm = Field(default_factory=dict)
    history: numeric_array((None,), most=10**6, limit=1e300) = Field(default_factory=list)


class PoseDocument(_Strict):
    frame: FrameNumber
    component: Name
    pose: fixed(6, Coordinate)
    match: MatchDocument | None
    reviewed: bool = False
    status: Literal[POSE_STATUSES]
    reason: Text


class ProjectDocument(_Strict):
    """A project's top level. ``records`` and ``poses`` are only counted here: each item is
    checked by ``RecordDocument`` / ``PoseDocument`` and ``item_problem`` as it is turned into
    the project (``io.project.document``), so that a large project is never held three times
    over (its JSON, its checked documents and the project) at once."""

    format: Literal["fluorogui-project"]
    schema_version: Annotated[int, Field(ge=1)]
    app_version: Text = ""
    views: bounded(ViewDocument, MAX_VIEWS)
    sequences: bounded(SequenceDocument, MAX_VIEWS)
    frames: bounded(FrameNumber, MAX_FRAMES)
    models: bounded(ModelDocument, 64)
    records: bounded(Any, 10**7)
    poses: bounded(Any, 10**7)
    settings: FreeForm

    @model_validator(mode="after")
    def _consistent(self):
        if len(self.sequences) != len(self.views):
            raise ValueError(f"{len(self.views)} views but {len(self.sequences)} image sequences")
        if len(set(self.frames)) != len(self.frames):
            raise ValueError("frames: a frame number is listed twice")
        for k, sequence in enumerate(self.sequences):
            problem = _sequence_problem(sequence, self.frames, f"sequences[{k}]")
            if problem:
                raise ValueError(problem)
        components = [m.component for m in self.models]
        if len(set(components)) != len(components):
            raise ValueError("models: a component is listed twice")
        for i, model in enumerate(self.models):
            if "\x00" in model.mesh_path:
                raise ValueError(f"models[{i}].mesh_path holds a NUL character, which no file name can")
            problem = rigid_problem(model.local_frame)
            if problem:
                raise ValueError(f"models[{i}].local_frame is not a rigid transform ({problem})")
        frames, views, models = len(self.frames), len(self.views), len(self.models)
        if len(self.records) > frames * views * models:  # before any item is checked or allocated
            raise ValueError(f"records holds {len(self.records):,} outlines, more than the {frames:,} frames x "
                             f"{views} views x {models} components can hold")
        if len(self.poses) > frames * models:
            raise ValueError(f"poses holds {len(self.poses):,} poses, more than the {frames:,} frames x "
                             f"{models} components can hold")
        return self


def _sequence_problem(sequence: SequenceDocument, frames: list[int], where: str) -> str | None:
    n, m = len(sequence.paths), len(frames)
    if n > m:
        return f"{where} has {n} images for {m} frames"
    for i, path in enumerate(sequence.paths):
        if "\x00" in path:
            return f"{where}.paths[{i}] holds a NUL character, which no file name can"
    if sequence.frames_without_image != list(frames[n:]):
        return (f"{where} has {n} image{'s' if n != 1 else ''} for {m} frames, so its 'frames_without_image' must "
                f"be {_listed(frames[n:])}, not {_listed(sequence.frames_without_image)}")
    return None


def _listed(frames: list[int]) -> str:
    """A list of frame numbers in a few characters: [], [40], [40, 41], [40 .. 99] (60 frames)."""
    if len(frames) <= 2:
        return "[" + ", ".join(map(str, frames)) + "]"
    return f"[{frames[0]} .. {frames[-1]}] ({len(frames)} frames)"


def item_problem(kind: str, index: int, item, frames: set, *, components: list, views: int) -> str | None:
    """What a checked record or pose contradicts in its project (a frame, component or view
    the project lacks; more per-view values than views), or None."""
    where = f"{kind}[{index}]"
    if item.frame not in frames:
        return f"{where} is for frame {item.frame}, which the project does not have"
    if item.component not in components:
        return f"{where} is for component {item.component!r}, which has no model"
    if kind == "records" and item.view >= views:
        return f"{where} is for view {item.view} but the project has {views} views"
    if kind == "poses" and item.match is not None and len(item.match.per_view_mean_mm) > views:
        return (f"{where}.match.per_view_mean_mm has {len(item.match.per_view_mean_mm)} values for the "
                f"project's {views} view{'s' if views != 1 else ''}")
    return None
