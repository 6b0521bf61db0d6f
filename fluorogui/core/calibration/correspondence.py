"""Which detected blob is which phantom bead: the correspondence search of the bead calibration.

The contract is the phantom file's: bead centres in 3D (mm), at least ``MIN_BEADS`` of
them, not (nearly) coplanar, the first one larger (the marker). Nothing else is assumed,
so regular grids on parallel plates, helices and scattered beads are all handled alike:

1. **Marker.** The largest blob, if its area is at least ``MARKER_AREA_RATIO`` times the
   median blob's; when the next-largest blobs come close to it, each is tried in turn.
2. **Hypotheses seeded at the marker.** Bases, each the marker and three phantom beads
   spanning a large tetrahedron with it (chosen to share few beads, so one hidden bead
   does not sink them all), are paired with every ordered triple of other detections.
   The four pairs fix an affine camera; a perspective camera needs a viewing axis and a
   distance too, and the affine camera gives the axis (``_perspective_guesses``), so each
   hypothesis is scored through its affine camera and through the perspective cameras at
   a few distances (``SCORE_DEPTHS``), by the number of *distinct* detections that some
   projected bead lands near (``_HitTable``). Perspective matters on a deep cage: two
   plates 120 mm apart seen from 750 mm differ in scale by 17 %, and an affine camera
   through the right seeds misses the far plate by tens of pixels, so the right hypothesis
   would rank in the thousands. Distinct detections matter on regular grids: there a
   camera that squeezes the phantom onto a few blobs would otherwise score best. Bases
   come in rounds (``_basis_rounds``); later rounds only while nothing has matched, for
   when the first bases' beads (the phantom's extremes) are outside the image.
3. **Refinement.** The best ``HYPOTHESES`` (up to ``MORE_HYPOTHESES`` while none has
   matched) are refined: the camera landing most beads on distinct detections among the
   perspective guesses at finer distances (``DEPTHS``) and a small seeded RANSAC over DLT
   cameras through the four seed pairs and two tentative ones; then the beads are
   re-paired (mutually nearest) and the DLT refitted until the pairs stop changing, pairs
   whose residual stands out (a merged blob, a speck) being dropped one by one.
4. **Choice.** Most inlier pairs, then the smallest RMS, among cameras a fluoroscope can
   be: proper (beads in front, ``det(P[:, :3]) > 0``; a mirrored camera is what a
   left-handed phantom file or a mirror-symmetric wrong match gives), with nearly zero
   skew, nearly square pixels and the principal point near the image's centre
   (``_is_plausible``), and fitted by a zero-skew pinhole about as well as by the DLT
   (``_fits_a_pinhole``). That rules out the ambiguity of two parallel grids, one plate
   matched a node over: a DLT fits that sheared phantom exactly, with the principal
   point hundreds of pixels off or skewed pixels. The marker bead must project onto the
   marker blob (within ``MARKER_REACH`` of its radius, not necessarily as an inlier: a
   bead touching the marker makes a merged blob whose centre is a little off), which
   rules out a whole grid matched a node over and two like plates seen as from the
   cage's other side. And the match must pair at least ``MIN_BEADS`` beads and
   ``MIN_SHARE`` of the detections (of the phantom's beads, if fewer): a DLT fits eight
   to ten wrong pairs of an unrelated phantom to a couple of pixels now and then.
   Otherwise a ``BeadError`` says what is missing; when the phantom mirrored would match,
   it says so.

After the search the blobs that are two beads merged are dropped (``_single_blobs``: with
perspective taken out they are larger than one bead), and the marker blob must be larger
than the small beads' on the same terms (``_apparent_sizes``), which rules out a near bead
taken for a marker that is outside the image. The camera maths (DLT, projection, pinhole)
is ``core.calibration.pinhole``.

Measured on generated cages (``fluorogui.simulation.cages``, 1024 px views tilted 0-60
degrees from the plates' normal, 500-1000 mm from the source, 160 random views per design:
``benchmarks/bench_cages.py --sweep 80 --seed 101``, then ``--seed 202``; without
``--sweep`` it reports the accuracy): none matched wrongly.
Matched: the 28-bead two-plate grid 159, a 32-bead one 160, plates 60 mm apart 160, 200 mm
apart 151, a 24-bead helix 156, 26 scattered beads 159, a dense 72-bead grid (two 6x6
plates) 79 of 80; the others refused because the marker is outside the image or does not
stand out from the near plate's beads, or because ten to fourteen beads were found, nearly
all on one plate. A view takes 0.2-0.4 s (28-32 beads; up to 3 s), the dense grid's about
1 s (up to 6: the enumeration grows as the cube of the number of blobs). Limits: a helix's
file that does not list the marker first still matches all but its end beads (a helix
shifted along itself is the same helix); a two-plate grid whose node is small against its
plates' gap (a sheared match moving the principal point less than a third of the image),
seen along the plates' normal, would be ambiguous.
"""
from __future__ import annotations

import itertools

import numpy as np
from scipy.spatial import cKDTree

from fluorogui.core.calibration.pinhole import decompose, dlt, dlt_conditioned, project, refine

MIN_BEADS = 8
MARKER_AREA_RATIO = 1.8
BASES, ALL_BASES = 5, 15  # phantom bases (marker + 3 beads) tried per round, and in all
HYPOTHESES = 10  # affine hypotheses refined perspectively ...
MORE_HYPOTHESES = 30  # ... and how far down the list to go while none has matched (per round)
SAMPLES = 16  # RANSAC samples per refined hypothesis
DEPTHS = 1.25 ** np.arange(2, 15)  # source-to-phantom distances tried, in phantom radii (1.6 to 23)
SCORE_DEPTHS = np.array([2.5, 4.0, 7.0])  # and those every hypothesis is scored at (besides affine)
MARKER_CANDIDATES = 3
# the marker bead must project within this share of the marker blob's radius of its centre: a
# bead touching the marker shifts the merged blob's centre by about a sixth of the radius
MARKER_REACH = 0.5
# with perspective taken out (_apparent_sizes), the marker blob at least MARKER_SIZE times a small
# bead's (a 5 mm marker among 2.5 mm beads: 4), a blob more than MERGED_SIZE times two beads merged
MARKER_SIZE, MERGED_SIZE = np.sqrt(MARKER_AREA_RATIO), 1.3
SCORED_BEADS = 32  # phantom beads (spread out) an affine hypothesis is scored on
WORK = 15_000_000  # projected beads over all affine hypotheses: fewer bases for a dense phantom
SAMPLE_SKEW, SAMPLE_ASPECT = 0.05, 1.25  # what a six-bead DLT of a fluoroscope can be
# what the match's DLT can be: right matches of generated cages < 1e-4 and 1.0001, XMALab's calibration
# of the real biplane data 0 and 1.0055; a 6x6 two-plate grid matched with one plate a node over: 0.006, 1.089
MAX_SKEW, MAX_ASPECT = 0.01, 1.05
# the principal point within a third of the image's size from its centre (the real biplane data's:
# 0.11); one plate of a two-plate grid matched a node over moves it by f x node / gap (0.6 of it)
CENTRE_REACH = 1 / 3
PINHOLE_FACTOR, PINHOLE_SLACK_PX = 1.5, 0.05
MIN_SHARE = 0.8  # of the detections (or of the phantom's beads, if fewer) a match must pair (right ones: > 0.9)
OUTLIER_FACTOR, RESIDUAL_FLOOR_PX = 4.0, 0.25  # a 2D residual 4x its median: 1 in 60000 for round noise
# a pair is an inlier within INLIER_SPACING x the median bead spacing in the image (at least
# INLIER_MIN_PX): right matches leave ~0.02 px on generated cages and a few tenths of a pixel on
# distortion-corrected images; a regular grid matched wrongly (a plate a node over, the cage
# seen as from its other side, a file whose marker is not first) leaves 2-5 % of the spacing
INLIER_SPACING, INLIER_MIN_PX = 0.02, 1.0


class BeadError(ValueError):
    """No calibration from these beads; ``about_phantom`` when the phantom file is at fault."""

    def __init__(self, message: str, about_phantom: bool = False):
        super().__init__(message)
        self.about_phantom = about_phantom


# ----------------------------------------------------------------------------- cameras


def _is_proper(P, points3) -> bool:
    """Beads in front and a right-handed camera (K with positive focal lengths, det R = +1)."""
    depth = np.column_stack([points3, np.ones(len(points3))]) @ P[2]
    return bool(np.all(depth > 0) and np.linalg.det(P[:, :3]) > 0)


def _is_plausible(P, max_skew=SAMPLE_SKEW, max_aspect=SAMPLE_ASPECT, frame=None) -> bool:
    """A fluoroscope's camera: skew below ``max_skew`` of the focal length, pixels within
    ``max_aspect`` of square and, when the image's ``frame`` (width, height) is given, the
    principal point within ``CENTRE_REACH`` of its size from its centre. ``K K^T`` comes
    from ``M M^T`` (M = P[:, :3] = K R) scaled to a unit last row, without a
    decomposition. A wrong correspondence that an 11-parameter DLT still fits gives absurd
    intrinsics (skew of several focal lengths, aspect 3). Two parallel grids with one plate
    matched a node over are the phantom sheared (x + s z, s the node over the plates'
    gap), which a DLT fits exactly: the camera's principal point moves by about ``f s``
    (600 px and more here) seen along the plates' normal, and its pixels skew or stretch
    seen obliquely (aspect 1.09 on a 6x6 grid seen at 33 degrees; ``_fits_a_pinhole``)."""
    M = P[:, :3] / np.linalg.norm(P[2, :3])
    A = M @ M.T
    cx, cy = A[0, 2], A[1, 2]
    fy2 = A[1, 1] - cy * cy
    if fy2 <= 0:
        return False
    fy = np.sqrt(fy2)
    skew = (A[0, 1] - cx * cy) / fy
    fx2 = A[0, 0] - skew * skew - cx * cx
    if fx2 <= 0:
        return False
    fx = np.sqrt(fx2)
    central = frame is None or (abs(cx - (frame[0] - 1) / 2) <= CENTRE_REACH * frame[0]
                                and abs(cy - (frame[1] - 1) / 2) <= CENTRE_REACH * frame[1])
    return bool(abs(skew) <= max_skew * fx and 1 / max_aspect <= fx / fy <= max_aspect and central)


def _fits_a_pinhole(P, points3, points2) -> bool:
    """Whether a zero-skew pinhole (its pixels free to be non-square) fits the pairs about as
    well as their DLT: within ``PINHOLE_FACTOR`` of its RMS plus ``PINHOLE_SLACK_PX``. On
    right matches the two agree to 0.1 %; a two-plate grid matched a node over, seen
    obliquely, leaves 0.35 px against the DLT's 0.014 on a 6x6 grid at 6 degrees."""
    residual = np.linalg.norm(project(P, points3) - points2, axis=1)
    K, R, t = refine(*decompose(P), points3=points3, points2=points2, square_pixels=False)
    pinhole = np.linalg.norm(project(K @ np.column_stack([R, t]), points3) - points2, axis=1)
    rms = float(np.sqrt(np.mean(residual**2)))
    return float(np.sqrt(np.mean(pinhole**2))) <= PINHOLE_FACTOR * rms + PINHOLE_SLACK_PX


def mutual_pairs(projected, detections, tolerance) -> list[tuple[int, int]]:
    """Mutually nearest (phantom bead, detection) pairs closer than ``tolerance``."""
    dist, nearest = cKDTree(detections).query(projected)
    back = cKDTree(projected).query(detections)[1]
    return [(i, int(j)) for i, (d, j) in enumerate(zip(dist, nearest)) if d < tolerance and back[j] == i]


def _distinct_hits(tree: cKDTree, projected, tolerance) -> int:
    j = tree.query(projected, distance_upper_bound=tolerance)[1]
    return len(np.unique(j[j < tree.n]))


# ---------------------------------------------------------------------------- the search


def _marker_candidates(centres, areas) -> list[int]:
    typical = float(np.median(areas))
    order = np.argsort(-areas, kind="stable")
    if areas[order[0]] < MARKER_AREA_RATIO * typical:
        ratio = areas[order[0]] / typical
        raise BeadError(f"found {len(centres)} beads; the marker bead (the phantom's first, larger one) could not be "
                        f"told apart: the largest blob is only {ratio:.2f}\u00d7 the median (need "
                        f"{MARKER_AREA_RATIO:.1f}\u00d7)")
    return [int(k) for k in order[:MARKER_CANDIDATES] if areas[k] >= max(MARKER_AREA_RATIO * typical,
                                                                        0.7 * areas[order[0]])]


def _bases(beads, count=BASES) -> list[tuple[int, int, int]]:
    """Triples of phantom beads spanning large tetrahedra with the marker, greedily chosen so
    that each shares few beads with those before it (volume halved per shared bead)."""
    triples = np.array(list(itertools.combinations(range(1, len(beads)), 3)), dtype=int)
    edges = beads[triples] - beads[0]
    volume = np.abs(np.linalg.det(edges))
    used = np.zeros(len(beads), dtype=int)
    chosen = []
    for _ in range(min(count, len(triples))):
        overlap = used[triples].sum(axis=1)
        k = int(np.argmax(volume * 0.5**overlap))
        if volume[k] <= 0:
            break
        chosen.append(tuple(int(i) for i in triples[k]))
        used[triples[k]] += 1
        volume[k] = -1.0
    return chosen


def _spread(beads, count) -> np.ndarray:
    """Indices of ``count`` beads spread over the phantom (farthest-point order from the marker)."""
    if len(beads) <= count:
        return np.arange(len(beads))
    chosen = [0]
    distance = np.linalg.norm(beads - beads[0], axis=1)
    while len(chosen) < count:
        k = int(np.argmax(distance))
        chosen.append(k)
        distance = np.minimum(distance, np.linalg.norm(beads - beads[k], axis=1))
    return np.array(chosen)


class _HitTable:
    """Which detection a pixel position is near: a raster of cells a quarter of the
    tolerance wide, each holding the detection nearest its centre if within the tolerance
    (so a hit is within 0.82 to 1.18 times it), with an empty border that positions
    outside fall onto. Five times faster than a k-d tree query on the hundreds of
    thousands of projected beads the hypotheses are scored on."""

    def __init__(self, centres, tolerance):
        self.missing = len(centres)
        self.cell = tolerance / 4
        self.origin = centres.min(axis=0) - tolerance - self.cell  # one empty cell before the first
        shape = np.ceil((centres.max(axis=0) + tolerance - self.origin) / self.cell).astype(int) + 2
        grid = np.stack(np.meshgrid(*(self.origin[d] + (np.arange(shape[d]) + 0.5) * self.cell for d in range(2)),
                                    indexing="ij"), axis=-1).reshape(-1, 2)
        table = cKDTree(centres).query(grid, distance_upper_bound=tolerance)[1].reshape(shape)
        table[[0, -1], :] = table[:, [0, -1]] = self.missing
        self.shape, self.table = shape, table.ravel()

    def distinct(self, u, v) -> np.ndarray:
        """Per hypothesis (u, v: Q, N, N projected beads each), how many distinct detections
        are hit; ``u`` and ``v`` finite."""
        cu = np.clip((u - float(self.origin[0])) * (1.0 / self.cell), 0, self.shape[0] - 1).astype(np.int32)
        cv = np.clip((v - float(self.origin[1])) * (1.0 / self.cell), 0, self.shape[1] - 1).astype(np.int32)
        hit = np.sort(self.table[cu * self.shape[1] + cv], axis=1)
        distinct = np.concatenate([np.ones((len(hit), 1), bool), hit[:, 1:] != hit[:, :-1]], axis=1)
        return ((hit < self.missing) & distinct).sum(axis=1)


def _times(a, b) -> np.ndarray:
    """``a @ b`` for a short inner dimension (4 or 3), without BLAS: its threads contend on a
    loaded machine and took 8 ms for what takes 0.5 ms here."""
    return np.einsum("qk,kn->qn", a, b)


def _basis_rounds(beads, detections) -> list[list[tuple[int, int, int]]]:
    """The phantom bases in rounds: as many per round as ``WORK`` allows (at most
    ``BASES``: a dense phantom seen with many blobs has one per round), ``ALL_BASES`` in
    all. Later rounds are tried only while nothing has matched: when the beads the first
    bases are made of (the phantom's extremes) lie outside the image or are hidden."""
    hypotheses = detections * (detections - 1) * (detections - 2) * min(len(beads), SCORED_BEADS)
    per_round = int(np.clip(WORK // max(hypotheses * (1 + len(SCORE_DEPTHS)), 1), 1, BASES))
    bases = _bases(beads, ALL_BASES)
    return [bases[k:k + per_round] for k in range(0, len(bases), per_round)]


def _affine_hypotheses(beads, centres, marker, tolerance, *, keep, bases) -> list[tuple[int, tuple, np.ndarray]]:
    """The ``keep`` best (score, basis, detection quadruple) over the ``bases`` and every
    ordered triple of detections other than the marker, a dense phantom being scored on
    ``SCORED_BEADS`` of its beads.

    Each hypothesis is scored through its affine camera and through the perspective
    cameras of ``_perspective_guesses`` at ``SCORE_DEPTHS`` (the best count counts): on a
    deep cage seen from close by, the affine camera through the right seeds misses most
    beads of the far plate, and the right hypothesis would otherwise rank in the
    thousands."""
    table = _HitTable(centres, tolerance)
    others = [k for k in range(len(centres)) if k != marker]
    combos = np.array(list(itertools.permutations(others, 3)), dtype=int).reshape(-1, 3)
    scored = _spread(beads, SCORED_BEADS)
    homogeneous = np.column_stack([beads[scored], np.ones(len(scored))])
    centre = beads.mean(axis=0)
    depths = SCORE_DEPTHS * float(np.max(np.linalg.norm(beads - centre, axis=1)))
    scores, owners = [], []
    for b, basis in enumerate(bases):
        seeds = beads[[0, *basis]]
        inverse = np.linalg.inv(np.column_stack([seeds, np.ones(4)]))
        C = (homogeneous @ inverse).T.astype(np.float32)  # the scored beads in terms of the 4 seeds, (4, n)
        inverse = inverse.astype(np.float32)  # single precision: ample for scoring, and much faster
        for start in range(0, len(combos), 20000):
            chunk = combos[start:start + 20000]
            # (Q, 4) pixels: seed k's detection in hypothesis q
            u = np.column_stack([np.full(len(chunk), centres[marker, 0]), centres[chunk, 0]]).astype(np.float32)
            v = np.column_stack([np.full(len(chunk), centres[marker, 1]), centres[chunk, 1]]).astype(np.float32)
            affine_u, affine_v = _times(u, C), _times(v, C)  # (Q, n): the scored beads through the affine cameras
            score = table.distinct(affine_u, affine_v)
            axis = np.cross(_times(u, inverse[:3].T), _times(v, inverse[:3].T))  # (Q, 3): their 2x3 parts' rows
            axis /= np.maximum(np.linalg.norm(axis, axis=1, keepdims=True), 1e-30)  # crossed (_perspective_guesses)
            along_seeds = _times(axis, (seeds - centre).T.astype(np.float32))  # (Q, 4) and (Q, n): how far along
            along_beads = _times(axis, (beads[scored] - centre).T.astype(np.float32))  # the axis from the centre
            # through the seeds with projective depths w = 1 + along / depth, divided by the beads' own
            slope_u, slope_v = _times(along_seeds * u, C), _times(along_seeds * v, C)
            for depth in depths.tolist():  # Python floats keep the arrays single
                reciprocal = 1.0 / np.maximum(1.0 + along_beads / depth, 1e-6)  # behind the source: far off
                score = np.maximum(score, table.distinct((affine_u + slope_u / depth) * reciprocal,
                                                         (affine_v + slope_v / depth) * reciprocal))
            scores.append(score)
            owners.append(np.column_stack([np.full(len(chunk), b), np.arange(start, start + len(chunk))]))
    scores, owners = np.concatenate(scores), np.concatenate(owners)
    best = np.argsort(-scores, kind="stable")[:keep]
    return [(int(scores[q]), bases[owners[q, 0]], np.array([marker, *combos[owners[q, 1]]])) for q in best]


def _inliers(beads, centres, pairs, spacing) -> tuple[list[tuple[int, int]], np.ndarray | None]:
    """The pairs left when the worst one is dropped, and the DLT refitted, while it stands
    out: beyond ``OUTLIER_FACTOR`` times the median residual (at least ``RESIDUAL_FLOOR_PX``),
    or beyond ``INLIER_SPACING`` of the bead spacing (at least ``INLIER_MIN_PX``), since an
    11-parameter DLT fits a wrong match of a regular grid to a few percent of the spacing.
    One at a time, because the DLT bends towards a bad pair (a merged blob a few pixels
    off) and hides it among the good ones' residuals until the worse ones are gone."""
    pairs = list(pairs)
    cap = max(INLIER_MIN_PX, INLIER_SPACING * spacing)
    while len(pairs) >= 6:
        idx3, idx2 = [i for i, _ in pairs], [j for _, j in pairs]
        P = dlt(beads[idx3], centres[idx2])
        residual = np.linalg.norm(project(P, beads[idx3]) - centres[idx2], axis=1)
        worst = int(np.argmax(residual))
        if residual[worst] <= min(max(RESIDUAL_FLOOR_PX, OUTLIER_FACTOR * float(np.median(residual))), cap):
            return pairs, P
        del pairs[worst]
    return pairs, None


def _apparent_sizes(P, beads, areas, pairs) -> np.ndarray:
    """Each pair's blob area times its bead's squared depth from the source, over the median
    of the small beads' (the marker, bead 0, left out of the median): perspective taken out,
    a single small bead is 1 (0.96-1.03 measured; a far one up to 1.13 where blur widens
    small blobs), two beads merged into one blob up to 2, the marker (d_marker / d_bead)^2."""
    depth = np.column_stack([beads[[i for i, _ in pairs]], np.ones(len(pairs))]) @ P[2]
    size = areas[[j for _, j in pairs]] * depth**2
    small = [k for k, (i, _) in enumerate(pairs) if i != 0]
    return size / np.median(size[small]) if small else size / size.max()


def _single_blobs(beads, centres, areas, pairs) -> list[tuple[int, int]]:
    """The match's pairs without the blobs that are two beads merged (``MERGED_SIZE``), the
    rest re-checked for outliers. A merged blob's centre lies between the beads' (1.7-2 px
    off on a 60 mm deep grid at 12 degrees), and an 11-parameter DLT bends towards it
    instead of showing it as an outlier (residuals up to 0.9 px, the right pairs' up to
    0.6). The search counts merged blobs as paired: they are explained detections."""
    size = _apparent_sizes(dlt(beads[[i for i, _ in pairs]], centres[[j for _, j in pairs]]), beads, areas, pairs)
    single = [pair for pair, s in zip(pairs, size) if pair[0] == 0 or s <= MERGED_SIZE]
    kept = single if len(single) == len(pairs) else _inliers(beads, centres, single, 0.0)[0]
    return kept if len(kept) >= MIN_BEADS else pairs


def _converge(P, beads, centres, tolerance) -> tuple[list[tuple[int, int]], np.ndarray | None]:
    """Re-pair and refit until the pairs stop changing; the inlier pairs and their DLT."""
    pairs: list[tuple[int, int]] = []
    for _ in range(12):
        kept, P = _inliers(beads, centres, mutual_pairs(project(P, beads), centres, tolerance), tolerance / 0.35)
        if P is None or not _is_proper(P, beads):
            return kept, None
        if kept == pairs:
            break
        pairs = kept
    return pairs, P


def _through_seeds(third_row, X, x) -> np.ndarray:
    """The camera with this third row (projective depth) through the four seed pairs
    (``X`` homogeneous 4x4, ``x`` pixels 4x2): its first two rows solve four equations each."""
    w = X @ third_row
    return np.vstack([np.linalg.solve(X, w * x[:, 0]), np.linalg.solve(X, w * x[:, 1]), third_row])


def _perspective_guesses(X, x, beads) -> list[np.ndarray]:
    """Perspective cameras through the four seed pairs, from their affine camera.

    Near the seeds an affine camera is the perspective one's linearisation: its 2x3 part
    is ``(f r1 + (c - u0) r3, f r2 + (c - u0) r3) / Z0`` with ``u0`` the image of the
    phantom's centre, so with the pixels taken about the seeds' mean the cross product of
    its rows points along the viewing axis ``r3`` (to within the principal point's offset
    over the focal length, a few degrees). What the affine camera cannot tell is the
    distance ``Z0`` from the source; it is scanned over ``DEPTHS`` times the phantom's
    radius, both ways along the axis. Each third row ``(r3 / Z0, 1 - r3 . X0 / Z0)`` then
    fixes the first two through the seeds (``_through_seeds``). Seeds spanning two
    plates 120 mm apart seen from 750 mm are off by up to 60 px affinely, by a few pixels
    here."""
    mean = x.mean(axis=0)
    affine = np.linalg.solve(X, x - mean).T
    axis = np.cross(affine[0, :3], affine[1, :3])
    if not np.any(axis):
        return []
    axis /= np.linalg.norm(axis)
    centre = beads.mean(axis=0)
    radius = float(np.max(np.linalg.norm(beads - centre, axis=1)))
    shift = np.array([[1.0, 0.0, mean[0]], [0.0, 1.0, mean[1]], [0.0, 0.0, 1.0]])
    guesses = []
    for sign in (1.0, -1.0):
        for depth in DEPTHS * radius:
            third = np.append(sign * axis / depth, 1.0 - sign * axis @ centre / depth)
            try:
                guesses.append(shift @ _through_seeds(third, X, x - mean))
            except np.linalg.LinAlgError:
                continue
    return guesses


def _refine_hypothesis(basis, quadruple, beads, centres, *, tolerance, rng):
    """Perspective refinement of one affine hypothesis: (pairs, P) or ([], None)."""
    seeds3, seeds2 = [0, *basis], list(quadruple)
    X = np.column_stack([beads[seeds3], np.ones(4)])
    affine = np.linalg.solve(X, centres[seeds2]).T  # 2x4
    predicted = np.column_stack([beads, np.ones(len(beads))]) @ affine.T
    tree = cKDTree(centres)
    dist, nearest = tree.query(predicted, distance_upper_bound=1.5 * tolerance)
    order = np.argsort(dist)
    taken, tentative = set(seeds2), []
    for i in order:
        j = int(nearest[i])
        if i in seeds3 or j >= len(centres) or j in taken:
            continue
        taken.add(j)
        tentative.append((int(i), j))
    best, best_hits = None, 0
    for P in _perspective_guesses(X, centres[seeds2], beads):
        if not _is_proper(P, beads):
            continue
        hits = _distinct_hits(tree, project(P, beads), 0.5 * tolerance)
        if hits > best_hits:
            best, best_hits = P, hits
    if len(tentative) < 2 and best is None:
        return [], None
    all_pairs = list(itertools.combinations(range(len(tentative)), 2))
    picks = all_pairs if len(all_pairs) <= SAMPLES else [all_pairs[k] for k in
                                                         rng.choice(len(all_pairs), SAMPLES, replace=False)]
    for a, b in picks:
        idx3 = seeds3 + [tentative[a][0], tentative[b][0]]
        idx2 = seeds2 + [tentative[a][1], tentative[b][1]]
        P, conditioning = dlt_conditioned(beads[idx3], centres[idx2])
        if conditioning > 0.1 or not _is_proper(P, beads) or not _is_plausible(P):
            continue  # a degenerate sample, a mirrored or behind-the-source camera, or no fluoroscope
        hits = _distinct_hits(tree, project(P, beads), 0.5 * tolerance)
        if hits > best_hits:
            best, best_hits = P, hits
    if best is None:
        return [], None
    return _converge(best, beads, centres, tolerance)


def _search(beads, centres, areas, markers, *, tolerance, need, frame=None,
            rounds=None) -> tuple[list[tuple[int, int]], int]:
    """The best inlier pairs over every marker candidate's hypotheses, and their count
    (over the first ``rounds`` of bases, all by default)."""
    rng = np.random.default_rng(0)
    best, best_key = [], (0, 0.0)
    rounds = _basis_rounds(beads, len(centres))[:rounds]
    reach = MARKER_REACH * np.sqrt(areas / np.pi)  # of each blob taken for the marker
    for marker, bases in itertools.product(markers, rounds):
        if best_key[0] >= need:
            break  # this blob did serve as the marker, these bases as the seeds
        for rank, (_, basis, quadruple) in enumerate(_affine_hypotheses(beads, centres, marker, tolerance,
                                                                        keep=MORE_HYPOTHESES, bases=bases)):
            if rank >= HYPOTHESES and best_key[0] >= need:
                break  # the first ones matched; more only while nothing has
            pairs, P = _refine_hypothesis(basis, quadruple, beads, centres, tolerance=tolerance, rng=rng)
            if P is None or not _is_proper(P, beads) or not _is_plausible(P, MAX_SKEW, MAX_ASPECT, frame):
                continue
            if any(j == marker and i != 0 for i, j in pairs):
                continue  # the marker blob taken for a small bead: not this hypothesis's world
            if np.linalg.norm(project(P, beads[:1])[0] - centres[marker]) > reach[marker]:
                continue  # the marker elsewhere: a grid matched a node over, or the cage seen from its other side
            if _apparent_sizes(P, beads, areas, [(0, marker), *pairs])[0] < MARKER_SIZE:
                continue  # a near bead looking large: the marker is another blob, or outside the image
            points3, points2 = beads[[i for i, _ in pairs]], centres[[j for _, j in pairs]]
            key = (len(pairs), -float(np.sqrt(np.mean(np.sum((project(P, points3) - points2) ** 2, axis=1)))))
            if key > best_key and _fits_a_pinhole(P, points3, points2):
                best, best_key = pairs, key
    return sorted(best), best_key[0]


def match_beads(beads: np.ndarray, centres: np.ndarray, areas: np.ndarray, frame=None) -> list[tuple[int, int]]:
    """(phantom index, detection index) pairs, outliers left out; raises BeadError.

    ``frame``: the image's (width, height) in pixels, when known; the match's principal
    point must then lie inside it."""
    beads = np.asarray(beads, dtype=float)
    if len(centres) < MIN_BEADS:
        raise BeadError(f"too few beads found in the image: {len(centres)} (need at least {MIN_BEADS}; the "
                        f"phantom has {len(beads)})")
    markers = _marker_candidates(centres, areas)
    spacing = float(np.median(cKDTree(centres).query(centres, k=2)[0][:, 1]))
    tolerance = 0.35 * spacing
    need = max(MIN_BEADS, int(np.ceil(MIN_SHARE * min(len(beads), len(centres)))))
    pairs, found = _search(beads, centres, areas, markers, tolerance=tolerance, need=need, frame=frame)
    if found >= need:
        return sorted(_single_blobs(beads, centres, areas, pairs))
    if _search(beads * [1.0, 1.0, -1.0], centres, areas, markers, tolerance=tolerance, need=need, frame=frame,
                        rounds=1)[1] >= need:
        raise BeadError("the beads match the phantom only mirrored: are the phantom file's coordinates "
                        "left-handed?", about_phantom=True)
    fit = f"at most {found}" if found else "none"
    raise BeadError(f"the beads cannot be matched to the phantom: {fit} of the {len(centres)} detected beads fit "
                    f"one camera with the phantom's {len(beads)} (need {need}; is the marker bead in the image, and "
                    "the phantom file's first bead?)")
