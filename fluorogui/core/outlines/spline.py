"""Image outlines as periodic cubic splines and the point-to-spline distance of Eq. (4).

An outline is an ordered, closed, non-self-intersecting list of pixel points (u, v). The
spline g(t) goes through them (scipy's periodic ``splprep``, parameter = cumulative chord
length in pixels) and records its valid parameter range ``t_range``; it is evaluated
modulo that range. ``closest`` finds the nearest spline point of many query points fast
and to ~1e-7 px (k-d tree of a 0.5 px polyline, projection on the two chords at the
nearest vertex, then a safeguarded Newton step on t); ``closest_secant`` is the paper's
secant method, kept for comparison.
"""
from __future__ import annotations

import numpy as np
from scipy.interpolate import PPoly, splprep
from scipy.spatial import cKDTree

#: a step between consecutive outline points longer than this many times the median step
#: (and than GAP_MIN_PX) is a chord across missing edges, not part of the traced outline
GAP_FACTOR, GAP_MIN_PX = 4.0, 4.0


class OutlineError(ValueError):
    """An outline that cannot be turned into a closed spline."""


# -- polylines --------------------------------------------------------------------------------
def _row_lengths(v: np.ndarray) -> np.ndarray:
    """Lengths of the rows of (N, 2) ``v``, the same numbers as ``np.linalg.norm(v, axis=1)``
    (sqrt(x^2 + y^2); a sum of two is the same in either order) without its costly reduction
    over a short axis."""
    return np.sqrt(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1])


def _drop_repeated_points(points: np.ndarray) -> np.ndarray:
    """Remove consecutive duplicates, including a closing point equal to the first."""
    return points[_distinct(points)]


def _distinct(points: np.ndarray) -> np.ndarray:
    """Which points ``_drop_repeated_points`` keeps (a boolean mask)."""
    keep = np.ones(len(points), dtype=bool)
    if len(points) < 2:
        return keep
    keep[1:] = _row_lengths(np.diff(points, axis=0)) > 1e-9
    last = len(points) - 1
    while last > 0 and (not keep[last] or np.linalg.norm(points[last] - points[0]) <= 1e-9):
        keep[last] = False
        last -= 1
    return keep


def resample_closed_polyline(points, n: int | None = None, spacing: float | None = None) -> np.ndarray:
    """``n`` points (or one every ``spacing``) equally spaced along a closed polyline."""
    points = np.asarray(points, dtype=float)
    if (n is None) == (spacing is None):
        raise ValueError("give exactly one of n and spacing")
    closed = np.vstack([points, points[:1]])
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))])
    total = arc[-1]
    if n is None:
        if spacing <= 0:
            raise ValueError("spacing must be positive")
        n = max(3, int(round(total / spacing)))
    if n < 1:
        raise ValueError("n must be positive")
    if total <= 0:
        return np.repeat(points[:1], n, axis=0)
    targets = np.arange(n) * (total / n)
    return np.column_stack([np.interp(targets, arc, closed[:, 0]), np.interp(targets, arc, closed[:, 1])])


def outward_normals(closed) -> np.ndarray:
    """Unit outward normals (..., K, 2) of closed polylines' vertices (K, 2), or of a batch
    of them (..., K, 2), either orientation: the central difference turned a quarter,
    flipped where the shoelace area is negative."""
    p = np.asarray(closed, dtype=float)
    if p.shape[-2] < 3:  # too short for the slices below: the plain form
        return _outward_normals_rolled(p)
    # next minus previous vertex, written with slices (np.roll copies twice as much)
    tangent = np.empty_like(p)
    np.subtract(p[..., 2:, :], p[..., :-2, :], out=tangent[..., 1:-1, :])
    np.subtract(p[..., 1, :], p[..., -1, :], out=tangent[..., 0, :])
    np.subtract(p[..., 0, :], p[..., -2, :], out=tangent[..., -1, :])
    normal = np.empty_like(p)
    normal[..., 0] = tangent[..., 1]
    np.negative(tangent[..., 0], out=normal[..., 1])
    # the length as np.linalg.norm computes it: sqrt(n_u^2 + n_v^2)
    length = np.sqrt(normal[..., 0] * normal[..., 0] + normal[..., 1] * normal[..., 1])
    normal /= np.maximum(length, 1e-12)[..., None]
    # twice the shoelace area: the sum of x_i y_(i+1) - x_(i+1) y_i, in the same order
    x, y = p[..., 0], p[..., 1]
    terms = np.empty(x.shape)
    np.subtract(x[..., :-1] * y[..., 1:], x[..., 1:] * y[..., :-1], out=terms[..., :-1])
    np.subtract(x[..., -1] * y[..., 0], x[..., 0] * y[..., -1], out=terms[..., -1])
    area2 = np.sum(terms, axis=-1)
    return np.where((area2 > 0)[..., None, None], normal, -normal)


def _outward_normals_rolled(p: np.ndarray) -> np.ndarray:
    """``outward_normals`` written with np.roll (any number of vertices)."""
    tangent = np.roll(p, -1, axis=-2) - np.roll(p, 1, axis=-2)
    normal = np.stack([tangent[..., 1], -tangent[..., 0]], axis=-1)
    normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-12)
    x, y = p[..., 0], p[..., 1]
    area2 = np.sum(x * np.roll(y, -1, axis=-1) - np.roll(x, -1, axis=-1) * y, axis=-1)
    return np.where((area2 > 0)[..., None, None], normal, -normal)


def _orientation(a, b, c) -> np.ndarray:
    return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])


def self_intersections(points) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Where the closed polygon ``points`` is not simple: the indices i of segments
    (points[i] -> points[i+1]) that fold back onto the next one (spikes), and the pairs
    (i, j), i < j, of non-adjacent segments that touch or cross.

    Sweep along u: segments are sorted by their left end and only pairs whose u-ranges
    overlap are tested, so typical outlines cost O(n log n)."""
    p = np.asarray(points, dtype=float)
    n = len(p)
    if n < 3:
        return np.zeros(0, dtype=int), []
    a, b = p, np.roll(p, -1, axis=0)
    # a segment reversing onto the next one (a spike) is a crossing as well
    d0, d1 = b - a, np.roll(b - a, -1, axis=0)
    cross = d0[:, 0] * d1[:, 1] - d0[:, 1] * d1[:, 0]
    dot = np.einsum("ij,ij->i", d0, d1)
    length = _row_lengths(d0)
    scale = length * np.roll(length, -1)  # d1 is d0 rolled: so are its lengths
    folds = np.flatnonzero((np.abs(cross) <= 1e-12 * scale) & (dot < 0))
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    order = np.argsort(lo[:, 0], kind="stable")
    lo_sorted_u = lo[order, 0]
    ends = np.searchsorted(lo_sorted_u, hi[order, 0], side="right")
    counts = ends - np.arange(n) - 1
    counts = np.maximum(counts, 0)
    first = np.repeat(np.arange(n), counts)
    second = first + 1 + (np.arange(first.size) - np.repeat(np.cumsum(counts) - counts, counts))
    i, j = order[first], order[second]
    gap = np.abs(i - j)
    candidate = (gap != 1) & (gap != n - 1) & (lo[i, 1] <= hi[j, 1]) & (lo[j, 1] <= hi[i, 1])
    i, j = i[candidate], j[candidate]
    o1, o2 = _orientation(a[i], b[i], a[j]), _orientation(a[i], b[i], b[j])
    o3, o4 = _orientation(a[j], b[j], a[i]), _orientation(a[j], b[j], b[i])
    crossing = (o1 * o2 <= 0) & (o3 * o4 <= 0)
    pairs = sorted(zip(np.minimum(i[crossing], j[crossing]).tolist(), np.maximum(i[crossing], j[crossing]).tolist()))
    return folds, pairs


def first_self_intersection(points) -> int | None:
    """Index of the first segment (points[i] -> points[i+1]) of the closed polygon that
    touches or crosses a non-adjacent segment, or folds back onto its neighbour; else None."""
    folds, pairs = self_intersections(points)
    hits = ([int(folds[0])] if folds.size else []) + ([pairs[0][0]] if pairs else [])
    return min(hits) if hits else None


def untangle_outline(points, max_rounds: int = 200) -> np.ndarray:
    """A simple closed polygon from one with small loops and spikes: each crossing cuts
    the polygon into two loops and the shorter one (fewer points) is dropped; a spike loses
    its tip. Edge chains merged along a prediction can cross where two pieces overlap;
    this repairs that instead of refusing the whole outline. Stops early (and returns what
    it has) after ``max_rounds`` repairs or below 4 points."""
    pts = _drop_repeated_points(np.asarray(points, dtype=float))
    for _ in range(max_rounds):
        if len(pts) < 4:
            break
        folds, pairs = self_intersections(pts)
        if not pairs and not folds.size:
            break
        n = len(pts)
        if folds.size:
            pts = np.delete(pts, (int(folds[0]) + 1) % n, axis=0)
        else:
            i, j = pairs[0]
            inner = np.arange(i + 1, j + 1)  # points between the two crossing segments
            outer = np.r_[np.arange(j + 1, n), np.arange(0, i + 1)]
            pts = np.delete(pts, inner if len(inner) <= len(outer) else outer, axis=0)
        pts = _drop_repeated_points(pts)
    return pts


#: at most this share of a refined outline's points may go to cut out its small loops
MAX_UNTANGLED = 0.05


def simple_or_plain(refined: np.ndarray, plain: np.ndarray) -> np.ndarray:
    """``refined`` if it is a simple closed polygon; else with its small loops cut out
    (``untangle_outline``) if that costs at most ``MAX_UNTANGLED`` of its points;
    else ``plain``. Moves along the model's normals can cross where the outline comes
    close to itself, and a stray's gap can leave a step that folds back: a crossing
    outline cannot be fitted, and one odd stretch must not cost the whole refinement."""
    if first_self_intersection(refined) is None:
        return refined
    untangled = untangle_outline(refined)
    if len(untangled) >= (1.0 - MAX_UNTANGLED) * len(refined) and first_self_intersection(untangled) is None:
        return untangled
    return np.asarray(plain, dtype=float).copy()


def validate_outline(points) -> np.ndarray:
    """The outline as a float (K, 2) array; raises OutlineError if it is unusable."""
    try:
        pts = np.asarray(points, dtype=float)
    except (TypeError, ValueError):
        raise OutlineError("outline is not a list of (u, v) numbers") from None
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise OutlineError(f"outline must be a (K, 2) array of (u, v) points, got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(pts), axis=1))[0])
        raise OutlineError(f"outline point {bad} is NaN or infinite")
    unique = _drop_repeated_points(pts)
    if len(unique) < 4:
        raise OutlineError(f"outline has {len(unique)} points; at least 4 are needed")
    where = first_self_intersection(unique)
    if where is not None:
        # report the index in the caller's list, not in the de-duplicated one
        original = int(np.flatnonzero(np.all(np.isclose(pts, unique[where], atol=1e-9, rtol=0), axis=1))[0])
        raise OutlineError(f"outline crosses itself at point {original}")
    return pts


def _unit_interval(x: np.ndarray) -> np.ndarray:
    """``x`` clipped to [0, 1] (np.clip's wrapper costs more than the work on short arrays)."""
    return np.minimum(np.maximum(x, 0.0), 1.0)


# -- the spline -------------------------------------------------------------------------------
class OutlineSpline:
    """Closed cubic spline g(t) through an ordered outline; t in pixels of chord length."""

    #: spacing (px) of the cached polyline that measures arc length (length_px, sample)
    POLYLINE_SPACING_PX = 0.25
    #: spacing (px) of the polyline whose nearest vertex seeds the closest-point search
    SEED_SPACING_PX = 0.5

    def __init__(self, tck, t_range):
        knots, coefficients, degree = tck
        self.tck = (np.asarray(knots, dtype=float), [np.asarray(c, dtype=float) for c in coefficients], int(degree))
        self.t_range = (float(t_range[0]), float(t_range[1]))
        if not self.t_range[1] > self.t_range[0]:
            raise OutlineError("spline parameter range is empty")
        knots, coefficients, degree = self.tck
        pieces = [PPoly.from_spline((knots, c, degree)) for c in coefficients]
        # piecewise-polynomial form (intervals, 4, 2) for fast vectorised evaluation
        self._breaks = pieces[0].x
        self._coeffs = np.ascontiguousarray(np.stack([piece.c.T for piece in pieces], axis=-1))
        # the same by power first (order, intervals, 2): a gather along the pieces then gives
        # each power's (N, 2) block contiguous, which halves the arithmetic's cost
        self._coeffs_by_power = np.ascontiguousarray(np.moveaxis(self._coeffs, 1, 0))
        self._polyline = None
        self._seed_polyline = None
        self._outward = None
        self._lookup = None
        self.length_px = float(self._dense_polyline()[2][-1])
        #: (G, 2) parameter intervals where the outline bridges a gap between its points (a
        #: chord across missing or hidden edges); set by ``fit``, empty when unknown
        self.gaps = np.zeros((0, 2))
        #: how much each stretch of the outline counts in a match (``weight_at``): (parameters,
        #: relative weights, mean 1) of the fitted points, or None for all alike
        self.point_weights: tuple[np.ndarray, np.ndarray] | None = None

    # -- construction ------------------------------------------------------------------------
    @classmethod
    def fit(cls, points, smoothing: float = 0.0, weights=None) -> "OutlineSpline":
        """Periodic cubic spline through ordered outline points (K, 2).

        ``smoothing`` is the expected RMS noise of the points in px: 0 interpolates (no
        shrinkage at all); a positive value lets the spline deviate from the points by about
        that much (scipy's s = K * smoothing**2), which removes edge jitter but rounds
        corners sharper than a few pixels slightly. ``weights`` (K, positive) say how much
        each point's stretch of the outline counts in a match (``weight_at``): the inverse
        variance of where a point was found, relative to the others.
        """
        pts = validate_outline(points)
        kept = _distinct(pts)
        pts = pts[kept]
        closed = np.vstack([pts, pts[:1]])
        u = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))])
        s = float(len(pts)) * float(smoothing) ** 2
        tck, _ = splprep([closed[:, 0], closed[:, 1]], u=u, s=s, k=3, per=1, quiet=2)
        spline = cls(tck, (u[0], u[-1]))
        steps = np.diff(u)
        bridge = steps > max(GAP_MIN_PX, GAP_FACTOR * float(np.median(steps)))
        spline.gaps = np.column_stack([u[:-1][bridge], u[1:][bridge]])
        if weights is not None:
            w = np.asarray(weights, dtype=float).reshape(-1)
            if len(w) != len(kept) or not np.all(np.isfinite(w) & (w > 0)):
                raise OutlineError(f"outline weights must be {len(kept)} positive numbers")
            w = w[kept]
            spline.point_weights = (u[:-1], w / w.mean())
        return spline

    def weight_at(self, t) -> np.ndarray:
        """The relative weight of the outline at parameters t (linear between the fitted
        points; 1 everywhere when the outline was fitted without weights)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self.point_weights is None:
            return np.ones(len(t))
        at, w = self.point_weights
        return np.interp(self.wrap(t), at, w, period=self.period)

    def to_dict(self) -> dict:
        knots, coefficients, degree = self.tck
        return {
            "knots": knots.tolist(),
            "coefficients": [c.tolist() for c in coefficients],
            "degree": degree,
            "t_range": list(self.t_range),
        } | ({} if self.point_weights is None else
             {"weights": [self.point_weights[0].tolist(), self.point_weights[1].tolist()]})

    @classmethod
    def from_dict(cls, d: dict) -> "OutlineSpline":
        try:
            spline = cls((d["knots"], d["coefficients"], d["degree"]), d["t_range"])
            if d.get("weights") is not None:
                spline.point_weights = tuple(np.asarray(x, dtype=float) for x in d["weights"])
            return spline
        except KeyError as exc:
            raise OutlineError(f"spline is missing the field {exc.args[0]!r}") from None

    # -- evaluation --------------------------------------------------------------------------
    @property
    def period(self) -> float:
        return self.t_range[1] - self.t_range[0]

    def wrap(self, t) -> np.ndarray:
        """Parameters mapped into [t0, t1)."""
        t0, period = self.t_range[0], self.period
        offset = np.asarray(t, dtype=float) - t0
        # mostly all are in range already, where np.mod (several times dearer than the test)
        # returns its argument unchanged (a zero as +0, which adds to t0 as -0 does)
        if offset.size and offset.min() >= 0.0 and offset.max() < period:
            return t0 + offset
        return t0 + np.mod(offset, period)

    def evaluate(self, t, order: int = 0) -> np.ndarray:
        """Points (N, 2) of g (or its ``order``-th derivative) at parameters t (wrapped)."""
        return self._evaluate_all(np.atleast_1d(t), order)[order]

    def _evaluate_all(self, t, max_order: int = 2) -> list[np.ndarray]:
        """g and its derivatives up to ``max_order`` at t (wrapped), each (N, 2)."""
        t = self.wrap(t)
        c = self._coeffs
        k = c.shape[1] - 1
        i = self._interval(t)
        dx = (t - self._breaks.take(i))[:, None]
        if k == 3:  # the cubic case written out: about twice as fast as the general loop
            # (take, not c[i]: numpy's fancy indexing costs several times more here)
            a, b, cc, d = self._coeffs_by_power.take(i, axis=1)
            ax = a * dx
            out = [((ax + b) * dx + cc) * dx + d]
            if max_order >= 1:
                out.append((3.0 * ax + 2.0 * b) * dx + cc)
            if max_order >= 2:
                out.append(6.0 * ax + 2.0 * b)
            return out
        local = c[i]  # (N, order, 2), highest power first
        out = []
        for order in range(max_order + 1):
            acc = local[:, 0] * self._falling(k, order)
            for j in range(1, k - order + 1):  # Horner on the order-th derivative
                acc = acc * dx + self._falling(k - j, order) * local[:, j]
            out.append(acc)
        return out

    def _interval(self, t: np.ndarray) -> np.ndarray:
        """Index of the polynomial piece holding each t (t already wrapped)."""
        breaks, n_pieces = self._breaks, self._coeffs.shape[0]
        if self._lookup is None:
            widths = np.diff(breaks)
            width = max(float(np.min(widths[widths > 0])), self.period / 1e6)
            start = float(breaks[0])
            n_bins = int(np.ceil((breaks[-1] - start) / width)) + 1
            if n_bins > 4 * n_pieces + 1024:  # very uneven pieces: binary search instead
                self._lookup = (start, 0.0, None)
            else:
                edges = start + np.arange(n_bins) * width
                piece = np.clip(np.searchsorted(breaks, edges, side="right") - 1, 0, n_pieces - 1)
                self._lookup = (start, width, piece)
        start, width, table = self._lookup
        if table is None:
            return np.minimum(np.maximum(np.searchsorted(breaks, t, side="right") - 1, 0), n_pieces - 1)
        # (np.minimum/maximum: np.clip's wrapper costs more than the work on these short arrays)
        i = table.take(np.minimum(np.maximum(((t - start) / width).astype(np.int64), 0), len(table) - 1))
        # a bin is narrower than any piece, so the piece is the tabled one or the next
        return np.minimum(i + (t >= breaks.take(np.minimum(i + 1, n_pieces))), n_pieces - 1)

    @staticmethod
    def _falling(power: int, order: int) -> float:
        """d^order/dx^order of x^power divided by x^(power - order)."""
        return float(np.prod(np.arange(power - order + 1, power + 1))) if order else 1.0

    def derivative(self, t, order: int = 1) -> np.ndarray:
        return self.evaluate(t, order)

    def _dense_polyline(self):
        """Cached (points, parameters, cumulative arc length) at <= 0.25 px spacing."""
        if self._polyline is None:
            t, pts, chord2 = self._polyline_at(self.POLYLINE_SPACING_PX)
            self._polyline = (pts, t, np.concatenate([[0.0], np.cumsum(np.sqrt(chord2))]))
        return self._polyline

    def _polyline_at(self, spacing: float):
        """Parameters (n + 1,) from t0 to t1, the n points before t1 (chords <= spacing) and
        the closed polyline's n squared chord lengths."""
        n = 64
        while True:
            t = self.t_range[0] + np.arange(n + 1) * (self.period / n)
            pts = self.evaluate(t[:-1])
            chords = np.empty_like(pts)
            np.subtract(pts[1:], pts[:-1], out=chords[:-1])
            np.subtract(pts[0], pts[-1], out=chords[-1])
            # squared lengths as np.linalg.norm sums them; the longest chord is the root of
            # the largest (the square root is monotonic), taken once instead of n times
            chord2 = chords[:, 0] * chords[:, 0] + chords[:, 1] * chords[:, 1]
            longest = np.sqrt(chord2.max())
            if longest <= spacing or n > 1 << 22:
                return t, pts, chord2
            n = int(np.ceil(n * longest / spacing * 1.05))

    def _seed_tree(self):
        """Cached k-d tree of the polyline used to seed ``closest``."""
        if self._seed_polyline is None:
            t, pts, _ = self._polyline_at(self.SEED_SPACING_PX)
            chords = np.roll(pts, -1, axis=0) - pts
            # each chord's squared length, once per spline instead of per query point
            chord2 = np.einsum("ij,ij->i", chords, chords)
            self._seed_polyline = (pts, t, cKDTree(pts, leafsize=16), chords, chord2)
        return self._seed_polyline

    def sample(self, n: int, skip_gaps: bool = False) -> np.ndarray:
        """``n`` points (n, 2) equally spaced in arc length, starting at t0; with
        ``skip_gaps`` the ones on chords across gaps (``gaps``) are left out."""
        return self.evaluate(self.sample_params(n, skip_gaps))

    def sample_params(self, n: int, skip_gaps: bool = False) -> np.ndarray:
        """The parameters (in [t0, t1)) of the points ``sample`` gives."""
        pts, t, arc = self._dense_polyline()
        targets = np.arange(n) * (arc[-1] / n)
        params = np.interp(targets, arc, t)
        if skip_gaps:
            params = params[~self.in_gap(params)]
        return params

    def in_gap(self, t) -> np.ndarray:
        """True for parameters on a chord across a gap of the outline."""
        t = self.wrap(np.asarray(t, dtype=float))
        out = np.zeros(t.shape, dtype=bool)
        for a, b in self.gaps:
            out |= (t > a) & (t < b)
        return out

    def outward_sign(self) -> float:
        """Sign that turns (g'_v, -g'_u) into the outward normal: +1 when the outline has a
        positive shoelace area in (u, v), i.e. runs clockwise on screen (v down)."""
        if self._outward is None:
            pts = self._dense_polyline()[0]
            x, y = pts[:, 0], pts[:, 1]
            self._outward = 1.0 if np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0 else -1.0
        return self._outward

    def _unit_outward(self, d: np.ndarray) -> np.ndarray:
        """Unit outward normals from tangents (N, 2)."""
        sign = self.outward_sign()
        n = np.empty_like(d)
        np.multiply(d[:, 1], sign, out=n[:, 0])
        np.multiply(-d[:, 0], sign, out=n[:, 1])
        return n / _row_lengths(n)[:, None]

    # -- Eq. (4): point to spline distance ---------------------------------------------------------
    def closest(self, points, newton_steps: int = 1):
        """For query points (N, 2): distances (N,), closest spline points (N, 2), unit outward
        normals there (N, 2) and parameters t (N,).

        Signed distances, if needed, are ``sum(normals * (points - closest), axis=1)``.
        """
        p = np.atleast_2d(np.asarray(points, dtype=float))
        poly, tp, tree, chords, chord2 = self._seed_tree()
        _, k = tree.query(p)
        m = len(poly)
        before = (k - 1) % m
        # (take, not fancy indexing: several times cheaper on these short arrays)
        t_at, t_after = tp.take(k), tp.take(k + 1)
        t_before = tp.take(before) - np.where(k == 0, self.period, 0.0)
        # project on the chords before and after the nearest vertex; keep the nearer foot
        rel = p - poly.take(k, axis=0)
        along = chords.take(k, axis=0)
        w_after = _unit_interval(np.einsum("ij,ij->i", rel, along) / chord2.take(k))
        back = -chords.take(before, axis=0)
        w_before = _unit_interval(np.einsum("ij,ij->i", rel, back) / chord2.take(before))
        miss_after = rel - w_after[:, None] * along
        miss_before = rel - w_before[:, None] * back
        use_after = np.einsum("ij,ij->i", miss_after, miss_after) <= np.einsum("ij,ij->i", miss_before, miss_before)
        t = np.where(use_after, t_at + w_after * (t_after - t_at), t_at - w_before * (t_at - t_before))
        t, g, d1 = self._refine(p, t, t_before, t_after, steps=newton_steps)
        return _row_lengths(p - g), g, self._unit_outward(d1), self.wrap(t)

    def _refine(self, p, t, lo, hi, *, steps: int, start=None):
        """Safeguarded Newton on f(t) = g'(t) . (g(t) - p) = 0 inside [lo, hi]: a step is
        kept only where it brings g(t) closer to p (else halved next time); Gauss-Newton
        replaces Newton where the curve bends away so much that f' <= 0. Returns t, g, g'."""
        g, d1, d2 = self._evaluate_all(t, 2)
        r = g - p
        dist2 = np.einsum("ij,ij->i", r, r)
        damping = np.ones(len(p))
        for iteration in range(steps):
            f = np.einsum("ij,ij->i", d1, r)
            gn = np.einsum("ij,ij->i", d1, d1)
            fp = gn + np.einsum("ij,ij->i", d2, r)
            t_new = np.minimum(np.maximum(t - damping * f / np.where(fp > 1e-3 * gn, fp, gn), lo), hi)
            last = iteration == steps - 1
            new = self._evaluate_all(t_new, 1 if last else 2)
            r_new = new[0] - p
            dist2_new = np.einsum("ij,ij->i", r_new, r_new)
            better = dist2_new <= dist2
            t = np.where(better, t_new, t)
            g = np.where(better[:, None], new[0], g)
            d1 = np.where(better[:, None], new[1], d1)
            if not last:
                d2 = np.where(better[:, None], new[2], d2)
                r = g - p
                dist2 = np.where(better, dist2_new, dist2)
                damping = np.where(better, 1.0, 0.5 * damping)
        return t, g, d1

    def closest_secant(self, points, coarse_spacing_px: float = 2.0, tol: float = 1e-9, max_iter: int = 40):
        """The paper's Eq. (4): minimise |g(t) - p| by the secant method on the slope
        f(t) = g'(t) . (g(t) - p), started from the nearest of samples ``coarse_spacing_px``
        apart and kept inside the bracket around it (regula falsi, Illinois variant, when f
        changes sign across the bracket). Same return values as ``closest``; slower."""
        p = np.atleast_2d(np.asarray(points, dtype=float))
        n_coarse = max(16, int(np.ceil(self.length_px / coarse_spacing_px)))
        h = self.period / n_coarse
        grid = self.t_range[0] + np.arange(n_coarse) * h
        coarse = self.evaluate(grid)
        nearest = np.empty(len(p), dtype=np.int64)
        for start in range(0, len(p), 512):  # blocks keep the distance table small
            block = p[start:start + 512]
            nearest[start:start + 512] = np.argmin(((block[:, None, :] - coarse[None, :, :]) ** 2).sum(axis=2), axis=1)

        def slope(t):
            g, d1 = self._evaluate_all(t, 1)
            return np.einsum("ij,ij->i", d1, g - p)

        lo, hi = grid[nearest] - h, grid[nearest] + h
        f_lo, f_hi = slope(lo), slope(hi)
        bracketed = (f_lo <= 0) & (f_hi >= 0)
        t_a, t_b, f_a, f_b = lo, hi, f_lo, f_hi
        for _ in range(max_iter):
            denom = f_b - f_a
            safe = np.abs(denom) > 1e-300
            t_new = np.where(safe, t_b - f_b * (t_b - t_a) / np.where(safe, denom, 1.0), t_b)
            t_new = np.clip(t_new, lo, hi)
            f_new = slope(t_new)
            # bracketed points keep the end with the opposite sign (Illinois: halve the
            # stale end's value); the others continue as the plain secant method
            same_side = np.sign(f_new) == np.sign(f_b)
            keep_a = bracketed & same_side
            f_a = np.where(bracketed, np.where(keep_a, 0.5 * f_a, f_b), f_b)
            t_a = np.where(bracketed & keep_a, t_a, t_b)
            moved = np.abs(t_new - t_b)
            t_b, f_b = t_new, f_new
            if np.all((moved < tol) | (f_b == 0)):
                break
        t = self.wrap(t_b)
        g, d1 = self._evaluate_all(t, 1)
        return np.linalg.norm(p - g, axis=1), g, self._unit_outward(d1), t
