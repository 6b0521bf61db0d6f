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
from typing import Annotated, Any, Literal, Optional

import numpy as np
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, model_validator

from fluorogui.core.status import Status

MAX_NESTING = 64  # a project is 6 deep; a file nested deeper is not ours
MAX_INTEGER_DIGITS = 30
MAX_VIEWS = 16
MAX_FRAMES = 1_000_000
MAX_OUTLINE_POINTS = 100_000  # a traced outline has hundreds to thousands
MAX_TEXT = 4096  # names, paths, reasons
POSE_STATUSES = tuple(s.value for s in Status)


class DocumentError(ValueError):
    """A document that is not valid JSON within our limits; the message says why."""


# -- reading JSON within limits -----------------------------------------------------------------
def nesting_depth(text: str, limit: int = MAX_NESTING) -> int:
    """The deepest nesting of ``[`` / ``{`` in JSON ``text``, brackets inside strings not
    counted. Vectorised (numpy over the bracket and quote positions only), so a large
    project costs a fraction of a second."""
    data = np.frombuffer(text.encode("utf-8", "surrogatepass"), dtype=np.uint8)
    quotes = np.flatnonzero(data == 34)
    escaped = quotes[(quotes > 0) & (data[np.maximum(quotes - 1, 0)] == 92)]
    if escaped.size:  # a quote after an odd run of backslashes is part of the string (rare)
        keep = np.ones(quotes.size, dtype=bool)
        for at in escaped:
            run = 0
            while at - 1 - run >= 0 and data[at - 1 - run] == 92:
                run += 1
            keep[np.searchsorted(quotes, at)] = run % 2 == 0
        quotes = quotes[keep]
    brackets = np.flatnonzero((data == 91) | (data == 123) | (data == 93) | (data == 125))
    outside = np.searchsorted(quotes, brackets) % 2 == 0  # an even number of quotes before it
    brackets = brackets[outside]
    if not brackets.size:
        return 0
    steps = np.where((data[brackets] == 91) | (data[brackets] == 123), 1, -1)
    return int(np.cumsum(steps).max())


def _parse_int(text: str) -> int:
    if len(text.lstrip("-")) > MAX_INTEGER_DIGITS:
        raise DocumentError(f"a whole number with {len(text)} digits")
    return int(text)


def _parse_constant(text: str):
    raise DocumentError(f"{text} is not a number JSON allows")


def parse_json(text: str, limit: int = MAX_NESTING) -> Any:
    """JSON ``text`` as Python data; DocumentError when it is malformed, nested more than
    ``limit`` deep, or holds NaN, Infinity or huge integers. A number too large for a float
    (1e999) reads as inf, which the schema's finite checks refuse where it is."""
    if nesting_depth(text, limit) > limit:
        raise DocumentError(f"nested more than {limit} levels deep")
    try:
        return json.loads(text, parse_int=_parse_int, parse_constant=_parse_constant)
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
    paths: bounded(Text, MAX_FRAMES)


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


class MatchDocument(_Strict):
    objective_mm: NonNegative
    per_view_mean_mm: bounded(NonNegative, MAX_VIEWS)
    calls: Count
    seconds: NonNegative
    converged: bool
    method: Text
    settings: dict[str, Any]
    quality: dict[str, Any] = Field(default_factory=dict)
    history: numeric_array((None,), most=10**6, limit=1e300) = Field(default_factory=list)


class PoseDocument(_Strict):
    frame: FrameNumber
    component: Name
    pose: fixed(6, Coordinate)
    match: MatchDocument | None
    reviewed: bool = False
    status: Literal[POSE_STATUSES]
    reason: Text


class SettingsDocument(_Strict):
    """Free-form settings; the parts fluorogui reads must have the right kind."""

    model_config = ConfigDict(strict=True, extra="allow")
    gui: dict[str, Any] = Field(default_factory=dict)
    workflow: dict[str, dict[str, Any]] = Field(default_factory=dict)


class ProjectDocument(_Strict):
    format: Literal["fluorogui-project"]
    schema_version: Annotated[int, Field(ge=1)]
    app_version: Text = ""
    views: bounded(ViewDocument, MAX_VIEWS)
    sequences: bounded(SequenceDocument, MAX_VIEWS)
    frames: bounded(FrameNumber, MAX_FRAMES)
    models: bounded(ModelDocument, 64)
    records: bounded(RecordDocument, 10**7)
    poses: bounded(PoseDocument, 10**7)
    settings: dict[str, Any]

    @model_validator(mode="after")
    def _consistent(self):
        if len(self.sequences) != len(self.views):
            raise ValueError(f"{len(self.views)} views but {len(self.sequences)} image sequences")
        if len(set(self.frames)) != len(self.frames):
            raise ValueError("frames: a frame number is listed twice")
        for k, sequence in enumerate(self.sequences):
            if len(sequence.paths) > len(self.frames):
                raise ValueError(f"sequences[{k}] has {len(sequence.paths)} images for {len(self.frames)} frames")
        components = [m.component for m in self.models]
        if len(set(components)) != len(components):
            raise ValueError("models: a component is listed twice")
        frames = set(self.frames)
        for kind, items in (("records", self.records), ("poses", self.poses)):
            for i, item in enumerate(items):
                if item.frame not in frames:
                    raise ValueError(f"{kind}[{i}] is for frame {item.frame}, which the project does not have")
                if item.component not in components:
                    raise ValueError(f"{kind}[{i}] is for component {item.component!r}, which has no model")
                if kind == "records" and item.view >= len(self.views):
                    raise ValueError(f"{kind}[{i}] is for view {item.view} but the project has "
                                     f"{len(self.views)} views")
        return self


def check_settings(settings: dict) -> None:
    """Raise ValidationError when the parts of ``settings`` fluorogui reads have the wrong kind."""
    SettingsDocument.model_validate(settings)


def check_typed_settings(values: dict, defaults: dict, where: str) -> None:
    """Raise ValueError naming ``where.key`` when a stored setting does not have the kind of
    its default (number, whole number, true/false, text, list of numbers), is not finite,
    or is negative (every engine setting is a size, a count or a limit). Unknown keys pass."""
    for key, default in defaults.items():
        if key not in values:
            continue
        value, name = values[key], f"field '{where}.{key}'"
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        if isinstance(default, bool):
            ok, kind = isinstance(value, bool), "true or false"
        elif isinstance(default, int) or (default is None and key.endswith("points")):
            ok = (value is None and default is None) or (isinstance(value, int) and not isinstance(value, bool)
                                                          and 0 <= value <= 10**9)
            kind = "a whole number from 0 to 10^9"
        elif isinstance(default, float) or default is None:
            ok = (value is None and default is None) or (number and math.isfinite(value) and 0 <= value <= 1e9)
            kind = "a finite number from 0 to 10^9"
        elif isinstance(default, str):
            ok, kind = isinstance(value, str) and len(value) <= 100, "a short text"
        elif isinstance(default, tuple):
            ok = isinstance(value, list) and len(value) == len(default) and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
            kind = f"a list of {len(default)} numbers"
        else:
            continue
        if not ok:
            raise ValueError(f"{name} must be {kind}, not {_shown(value)}")
