"""Find implants: place every component in an image pair with no starting pose, or near a
predicted one (tracking recovery), and say honestly when it could not.

``find_components`` runs, per component (``shape_search`` has the machinery):

1. *Where.* Dark regions at many grey levels in each view; pairs of region centroids
   whose rays nearly meet give 3D position hypotheses (ten to fifty). All are ranked at
   once by a very quick scan (100 orientations, +/-48 px per view on blurred oriented
   edge maps); the best eight by a quick one (600 orientations, the best 20 scored again
   on sharp maps); the best one, or two when close, go on. Positions where another
   component was already found are skipped. If the component is not found, a second
   round adds depth peaks of the dark regions (a component merged with dark soft tissue
   has no region of its own). With ``near`` the predicted position is the only one.
2. *Which way round.* 4000 orientations (~9 degrees apart; with ``near`` only those
   within ``NEAR_DEG`` of the prediction, 6 degrees apart) are scored there with the
   silhouette templates; the best 300 again on the sharp maps, the best 40 of those
   turned by 5 degrees about each axis. The best ``KEEP`` distinct ones (20 degrees
   apart) are refined on exact silhouettes of a decimated mesh against the image edges
   (``refine_on_edges``), the best three finished on a finer mesh, and ranked by their
   edge score.
3. *Final fit.* The best candidate (and the runner-up when its edge score is within
   ``CLOSE_SCORE``) is matched on Canny outlines with the full mesh
   (``core.matching.loop.match_images``, one pass; a second when the pose moved more than
   ``SETTLED`` so that the outline was segmented along a different pose).
4. *The others masked.* Each component after the first is searched with the projections
   of those already found masked: in the edge maps (the pixels they cover score as a
   middling edge, ``MIN_EDGE_SCORE``, so an outline running behind them is neither
   rewarded nor punished), in its segmentation and fit, and in its verdict (the overlap
   is judged on what they leave free). One not found so is searched once more on the
   unmasked edge maps (its fit and verdict still masked): a masked pixel scores for free,
   so positions beside the others can outrank its own. A component not found is searched
   again once the others are. When none is found (overlapping components can each hide the other's
   outline), the surer miss (the best overlap, at least ``SURER_MIN_IOU``) is held where
   it fitted and masked while the others are searched again; if one is then found, the
   held one is searched again with it masked.
5. *Verdict.* ``found`` only when both views fit: mean outline distance per view at most
   ``MAX_VIEW_PX``, IoU of silhouette and image-outline region at least ``MIN_IOU`` and
   edge score at least ``MIN_EDGE_SCORE`` in each view; and when no candidate turned by
   more than 20 degrees fits about as well (a symmetric part, a flipped tibial tray)
   unless the Canny objective separates them by ``CLEAR_OBJECTIVE_PX``. Otherwise
   ``found`` is False and ``reason`` says why in words.

``Placement.iou`` is the silhouette IoU with the region enclosed by the image outline
segmented at the pose (half resolution), not with a thresholded dark region: those are
too poor (a tibial tray is lost, a femoral component merges with soft tissue) and only
propose positions here. Regions the outline only closes by a chord across a gap (a faint
stem) are left out where the silhouette lies on image edges (``outline_overlap``).

Measured on the real biplane data (benchmarks/bench_find.py, 2 shared cores): both
components right and found in every frame with a reference (26 femoral, 27 tibial), none
confidently wrong, about 1 s per frame for both (2.2 s at most); near a pose 5 mm and 15
degrees off, about 0.3 s per component.
"""
from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from fluorogui.core.cancel import check_cancel
from fluorogui.core.matching.loop import match_images
from fluorogui.core.projection.geometry import View
from fluorogui.core.projection.mesh import PreparedMesh
from fluorogui.core.projection.pose import angles_from_matrix, rotation_matrix, rotvec_matrix
from fluorogui.core.projection.silhouette import projected_region
from fluorogui.core.search import shape_search as ss
from fluorogui.core.search.orientation import orientation_grid
from fluorogui.core.search.outline_overlap import outline_iou

#: per-view mean outline distance above which a fit is not accepted, in px of a 1024-pixel image
#: (right on the real data: 0.35-0.7 px = 0.11-0.21 mm; wrong: >= 1.4 px). Pixels, not mm: a
#: calibration without a pixel pitch gets an assumed one
MAX_VIEW_PX = 1.0
#: per-view IoU of silhouette and image outline region below which a fit is not accepted
MIN_IOU = 0.94
#: per-view edge score below which a fit is not accepted (nor tried)
MIN_EDGE_SCORE = 0.6
#: the projection of a component already found is masked for the next, grown by this (px)
HIDE_MARGIN_PX = 3
#: best edge score after refinement below which no Canny fit is tried (right: >= ~0.8)
MIN_CANDIDATE_SCORE = 0.65
#: near mode: orientations within this many degrees of the predicted one
NEAR_DEG = 36.0
#: candidates whose edge scores differ by less than this are both matched on Canny outlines
CLOSE_SCORE = 0.08
#: ... and when their Canny objectives (summed mean outline distances, px of a 1024-pixel image)
#: differ by less than this they are ambiguous
CLEAR_OBJECTIVE_PX = 0.25

#: search radii (px) of the edge refinement: screening every candidate, then finishing the best
SCREEN_RADII, FINISH_RADII = (20, 12, 8, 5), (4, 3, 3, 3)
#: a Canny fit that moved less than this (centroid mm, rotation deg) from its start is not fitted again
SETTLED = 0.5
#: orientations of the blurred scan scored again on the sharper maps, and how many of those
#: are tried again turned by 5 degrees about each axis
RESCORE, LOCAL = 300, 40
#: distinct candidates screened by the edge refinement (global search; near: 4)
KEEP = 6
_LOCAL_STEPS = np.stack([rotvec_matrix(np.radians([a, b, c])) for a in (-5, 0, 5) for b in (-5, 0, 5)
                         for c in (-5, 0, 5)])

ProgressFn = Callable[[float, str], None]


@dataclass
class Placement:
    """Where :func:`find_components` put one component, and how sure it is.

    Attributes
    ----------
    component : str
    pose : numpy.ndarray or None
        mm and degrees (the pose convention), refined on Canny outlines; None if nothing
        usable was found.
    found : bool
        True only when the search is confident (both views fit, no other orientation fits
        about as well); only then is the pose stored.
    iou : list of float
        Per view, the overlap of the silhouette with the region inside the image outline.
    objective_mm : float
        The match objective on the Canny outlines at ``pose`` (NaN if none).
    per_view_mean_mm : list of float
        Mean outline distance per view.
    reason : str
        Empty when found; otherwise why not, in plain words.
    seconds : float
    edge_score : list of float
        Per view, the oriented edge score (about 0.8-1 at a right pose).
    alternatives : list
        ``(edge score, pose)`` of the candidates considered, best first.
    frame : int
        The frame it was searched in.
    """

    component: str
    pose: np.ndarray | None  # mm, deg (developer/conventions.rst), refined on Canny outlines; None if nothing usable
    found: bool  # True only when confident
    iou: list[float]  # per view: silhouette IoU with the region inside the image outline at `pose` (half resolution)
    objective_mm: float  # match objective on the Canny outlines at `pose` (sum over views of mean distance, mm) or nan
    per_view_mean_mm: list[float]
    reason: str  # '' when found; else a short user-facing reason
    seconds: float
    edge_score: list[float] = field(default_factory=list)  # per view, see shape_search (right: ~0.8-1)
    alternatives: list = field(default_factory=list)  # (edge score, pose) of the candidates considered, best first
    frame: int = 0  # the frame it was searched in (the workflow's frame number)

    def describe(self) -> str:
        """One line for the user: found (with its overlap) or why not.

        Examples
        --------
        >>> from fluorogui import Placement
        >>> Placement("tibial", None, False, [0.81, 0.77], float("nan"), [], "no candidate fits both views",
        ...           1.2).describe()
        'tibial: not placed (no candidate fits both views; overlap 79 %)'
        """
        overlap = f"overlap {100 * float(np.mean(self.iou)):.0f} %" if self.iou else "no overlap"
        if self.found:
            return f"{self.component}: found ({overlap})"
        return f"{self.component}: not placed ({self.reason}; {overlap})"


class _Steps:
    """Progress as a fraction of the whole job, and the cancel check."""

    def __init__(self, progress, cancel, n_components: int):
        self.progress, self.cancel, self.n = progress, cancel, max(1, n_components)
        self.k = 0  # component being searched
        self.name = ""
        self.hidden: list | None = None  # per view, where the components found so far project
        self.span = (0.0, 1.0)  # part of that component's share being reported

    def check(self):
        check_cancel(self.cancel)

    def report(self, within: float, text: str):
        self.check()
        if self.progress is not None:
            within = self.span[0] + (self.span[1] - self.span[0]) * within
            if self.name and not text.startswith(self.name):
                text = f"{self.name}: {text}"
            self.progress(min(1.0, 0.05 + 0.95 * (self.k + within) / self.n), text)


# -- candidates ----------------------------------------------------------------------------
@dataclass
class _Candidate:
    R: np.ndarray
    c: np.ndarray  # model centroid in the world
    scores: list[float]  # per-view edge score after refine_on_edges

    @property
    def score(self) -> float:
        return float(np.mean(self.scores))

    def pose(self, mesh: PreparedMesh) -> np.ndarray:
        return np.array([*(self.c - self.R @ mesh.centroid), *angles_from_matrix(self.R)])


def _angle_deg(Ra: np.ndarray, Rb: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(Ra.T @ Rb) - 1.0) / 2.0, -1.0, 1.0))))


def _pose_change(mesh: PreparedMesh, a, b) -> tuple[float, float]:
    """How far the model moves between poses a and b: centroid (mm), rotation (deg)."""
    Ra, Rb = rotation_matrix(*a[3:]), rotation_matrix(*b[3:])
    return (float(np.linalg.norm(Ra @ mesh.centroid + a[:3] - Rb @ mesh.centroid - b[:3])), _angle_deg(Ra, Rb))


#: angles (deg) this close to a threshold are taken one by one with ``_angle_deg``: the
#: batched trace sums its products in another order (a few 1e-16 apart)
_HAIR_DEG = 1e-6


def _distinct(order, rotations, k: int, min_deg: float = 20.0) -> list[int]:
    """The first ``k`` of ``order`` more than ``min_deg`` apart in rotation: each one
    taken is the first left, and removes those within ``min_deg`` of it from the rest,
    all at once (the one-by-one loop over ~1400 orientations took ~6 ms a centre). The
    same as keeping each ``i`` of ``order`` farther than ``min_deg`` from all those kept
    before it, an angle within a hair of ``min_deg`` taken as that rule takes it."""
    order = np.asarray(order, dtype=np.intp)
    left = np.ones(len(order), bool)
    out: list[int] = []
    while len(out) < k:
        free = np.flatnonzero(left)
        if not len(free):
            break
        first = free[0]
        kept = int(order[first])
        out.append(kept)
        rest = order[free[1:]]
        # trace(Ra.T @ Rb) of every pair at once: the sum of their elementwise products
        trace = np.einsum("ij,nij->n", rotations[kept], rotations[rest])
        angle = np.degrees(np.arccos(np.clip((trace - 1.0) / 2.0, -1.0, 1.0)))
        near = ~(angle > min_deg)
        for m in np.flatnonzero(~(np.abs(angle - min_deg) > _HAIR_DEG)):  # (and NaN)
            near[m] = not _angle_deg(rotations[kept], rotations[rest[m]]) > min_deg
        left[first] = False
        left[free[1:][near]] = False
    return out


def _moved_centre(views, c, shifts_px) -> np.ndarray:
    """Move the 3D point c so that its projections move by ``shifts_px`` (least squares)."""
    A, b = [], []
    for view, s in zip(views, shifts_px):
        _, J = view.project_jacobian(c[None, :])
        A.append(J[0])
        b.append(s)
    return c + np.linalg.lstsq(np.vstack(A), np.concatenate(b), rcond=None)[0]


def near_rotations(R: np.ndarray, max_deg: float = NEAR_DEG, step_deg: float = 6.0) -> np.ndarray:
    """Rotations exp(w) R with |w| <= max_deg on a cubic grid of rotation vectors."""
    return np.matmul(_near_turns(float(max_deg), float(step_deg)), R)


@functools.lru_cache(maxsize=4)
def _near_turns(max_deg: float, step_deg: float) -> np.ndarray:
    """The turns exp(w) of ``near_rotations``, made once (900 Rodrigues matrices took 10-15 ms
    of every search near a prediction)."""
    g = np.arange(-max_deg, max_deg + 1e-9, step_deg)
    w = np.array([(a, b, c) for a in g for b in g for c in g])
    w = np.radians(w[np.linalg.norm(w, axis=1) <= max_deg + 1e-9])
    turns = np.stack([rotvec_matrix(x) for x in w])
    turns.flags.writeable = False
    return turns


_GRIDS: dict[int, np.ndarray] = {}


def _grid(n: int) -> np.ndarray:
    if n not in _GRIDS:
        _GRIDS[n] = orientation_grid(n)
    return _GRIDS[n]


def _candidates(lib, views, maps, centres, *, rotations, shifts, keep: int, steps: _Steps, at: float, span: float,
                final: int = 3):
    """Scan ``rotations`` at every centre and keep the best ``keep`` distinct ones over all
    centres; screen them with a short refinement on the image edges, finish the best
    ``final``; sorted by edge score, best first."""
    found = []
    for h, centre in enumerate(centres):
        steps.report(at + span * 0.2 * h / max(1, len(centres)), "scanning orientations")
        score, best = ss.scan_orientations(lib, views, maps, centre, rotations=rotations, shifts_px=shifts)
        top = np.argsort(-score)[:RESCORE]  # the blurred maps rank well enough to shortlist, not to choose
        R = rotations[top]
        score, best = ss.rescore(lib, views, maps, centre, rotations=R, shifts=best[top], local_px=ss.shift_grid(12, 4))
        # the grid is ~9 degrees coarse: try 5-degree steps around the best, on the sharp maps
        k = np.argsort(-score)[:LOCAL]
        R_local = np.matmul(_LOCAL_STEPS[None], R[k][:, None]).reshape(-1, 3, 3)
        s_local, b_local = ss.rescore(lib, views, maps, centre, rotations=R_local, shifts=np.repeat(best[k],
                                                                                                    len(_LOCAL_STEPS),
                                                                                                    axis=0),
                                      local_px=ss.shift_grid(8, 4))
        R, score, best = np.concatenate([R, R_local]), np.r_[score, s_local], np.concatenate([best, b_local])
        for i in _distinct(np.argsort(-score), R, keep):
            found.append((score[i], R[i], _moved_centre(views, centre, best[i])))
    found.sort(key=lambda f: -f[0])
    out = []
    for k, (_, R, c) in enumerate(found[:keep]):
        if k % 3 == 0:
            steps.report(at + span * (0.2 + 0.6 * k / keep), "refining candidates on edges")
        R, c = ss.refine_on_edges(lib.coarse, views, maps, R, c=c, radii_px=SCREEN_RADII)
        out.append(_Candidate(R, c, ss.pose_edge_score(lib.coarse, R, c, views, maps=maps)))
    out.sort(key=lambda cand: -cand.score)
    for k, cand in enumerate(out[:final]):
        R, c = ss.refine_on_edges(lib.fine, views, maps, cand.R, c=cand.c, radii_px=FINISH_RADII)
        out[k] = _Candidate(R, c, ss.pose_edge_score(lib.coarse, R, c, views, maps=maps))
    steps.report(at + span, "refining candidates on edges")
    out[:final] = sorted(out[:final], key=lambda cand: -cand.score)
    distinct: list[_Candidate] = []  # several starts often end at the same pose
    for cand in out:
        if all(_angle_deg(cand.R, d.R) > 8.0 or np.linalg.norm(cand.c - d.c) > 4.0 for d in distinct):
            distinct.append(cand)
    return distinct


def _rank_hypotheses(lib, views, maps, hypotheses, *, steps: _Steps, at: float, span: float) -> list[np.ndarray]:
    """The one or two most promising positions. A very quick scan (100 orientations, all
    hypotheses in one batch) keeps eight, a quick one (600) keeps the best 20 orientations
    of each, and those are scored again on the sharp maps: blurred maps let a tibial
    outline half-fit the femoral component's edges. After each scan a hypothesis moves to
    where its best orientation fitted (the shifts found in both views), so one that
    started 15-30 mm off (a region centroid between two overlapping components) comes in."""
    shifts = ss.shift_grid(48, 16)
    scored = [np.asarray(h, float) for h in hypotheses]
    if not scored:
        return scored
    for n_rot, keep in ((100, 8), (600, 2)):
        steps.report(at + span * (0.5 if n_rot > 100 else 0.0), "looking for the component")
        rotations = _grid(n_rot)
        h = len(scored)
        centres = np.repeat(np.array(scored), n_rot, axis=0)
        score, best = ss.scan_orientations(lib, views, maps, centres, rotations=np.tile(rotations, (h, 1, 1)),
                                           shifts_px=shifts,
                                           chunk=4000)
        if n_rot == 600:  # the best 20 orientations of each hypothesis again on the sharp maps
            top = np.argsort(-score.reshape(h, n_rot), axis=1)[:, :20]
            rows = (np.arange(h)[:, None] * n_rot + top).ravel()
            fine, fine_best = ss.rescore(lib, views, maps, centres[rows], rotations=np.tile(rotations, (h, 1, 1))[rows],
                                         shifts=best[rows], local_px=ss.shift_grid(12, 4))
            score = np.full(h * n_rot, -np.inf)
            score[rows], best[rows] = fine, fine_best
        score = score.reshape(h, n_rot)
        arg = score.argmax(1)
        top_scores = score[np.arange(h), arg]
        moved = [_moved_centre(views, c, best[i * n_rot + arg[i]]) for i, c in enumerate(scored)]
        order = np.argsort(-top_scores)
        if n_rot == 600 and h > 1 and top_scores[order[1]] < top_scores[order[0]] - 0.04:
            keep = 1
        # after the very quick scan both a hypothesis and its moved self go on (the move
        # follows an orientation only roughly right); after the quick scan the moved one
        kept = []
        for i in order[:keep]:
            for c in ((scored[i], moved[i]) if n_rot == 100 else (moved[i],)):
                if all(np.linalg.norm(c - k) > 8.0 for k in kept):
                    kept.append(c)
        scored = kept
    return scored


# -- the final fit and the verdict ---------------------------------------------------------------
def _fit(images, views, mesh, pose, steps: _Steps):
    """One segment-and-match pass on Canny outlines from ``pose``, with the components found
    before masked (``steps.hidden``): (result, splines), or None when no usable outline is
    found along it."""
    try:
        res, splines = match_images(images, views, mesh, pose, passes=1, cancel=steps.cancel, occluded=steps.hidden)
    except ValueError:  # EdgeError / OutlineError / SegmentationError: nothing to match here
        return None
    return res, splines


def _assess(images, views, mesh, lib, *, maps, res, splines, hidden=None):
    """Per-view IoU of silhouette and outline region, and edge scores, at ``res.pose``, on
    what the components found before (``hidden``, per view) leave free."""
    pose = res.pose
    R = rotation_matrix(*pose[3:])
    hidden = hidden or [None] * len(views)
    iou = [outline_iou(mesh, pose, v, s, shape=img.shape[:2], hidden=m, image=img)
           for v, s, img, m in zip(views, splines, images, hidden)]
    return iou, ss.pose_edge_score(lib.coarse, R, R @ mesh.centroid + pose[:3], views, maps=maps, hidden=hidden)


def _objective_px(res, views, maps) -> float:
    """The match objective in px of a 1024-pixel image (summed over views)."""
    return float(sum(mm / v.mm_per_px() / m.unit for mm, v, m in zip(res.per_view_mean_mm, views, maps)))


def _verdict(res, iou, edge, views, maps) -> str:
    """'' when the fit is good in both views, else why not."""
    px = [mm / v.mm_per_px() / m.unit for mm, v, m in zip(res.per_view_mean_mm, views, maps)]
    worst = int(np.argmax(px))
    if px[worst] > MAX_VIEW_PX:
        return (f"outline distance {res.per_view_mean_mm[worst]:.2f} mm ({px[worst]:.1f} px) in view {worst + 1} "
                "is too large")
    k = int(np.argmin(iou))
    if iou[k] < MIN_IOU:
        return f"best overlap {iou[k]:.2f} in view {k + 1} is too low"
    k = int(np.argmin(edge))
    if edge[k] < MIN_EDGE_SCORE:
        return f"the outline in view {k + 1} is not on the image edges"
    return ""


def _conclude(name, mesh, lib, images, *, views, maps, cands, steps: _Steps, t0: float, where: str = "") -> Placement:
    """Fit the best candidates on Canny outlines and judge the result (``where`` qualifies
    the reason when nothing fits, e.g. " near the predicted pose")."""
    alternatives = [(c.score, c.pose(mesh)) for c in cands]
    cands = [c for c in cands if c.score >= MIN_CANDIDATE_SCORE and min(c.scores) >= MIN_EDGE_SCORE] or cands[:1]
    if not cands or cands[0].score < MIN_CANDIDATE_SCORE or min(cands[0].scores) < MIN_EDGE_SCORE:
        # nothing worth a Canny fit (which is slow where edges are faint)
        best = f" (edge scores {' / '.join(f'{v:.2f}' for v in cands[0].scores)})" if cands else ""
        return Placement(name, None, False, [], float("nan"), [], f"nothing{where} fits its outline{best}",
                         time.perf_counter() - t0, cands[0].scores if cands else [], alternatives)
    steps.report(0.6, f"{name}: fitting on Canny outlines")
    fits = []  # first pass on Canny outlines from the best candidate and a close runner-up
    for k, cand in enumerate(cands[:3]):
        if k > 0 and (cand.score < cands[0].score - CLOSE_SCORE or len(fits) >= 2):
            break
        fit = _fit(images, views, mesh, cand.pose(mesh), steps)
        if fit is not None:
            fits.append((*fit, cand.pose(mesh)))
        steps.report(0.6 + 0.12 * (k + 1), f"{name}: fitting on Canny outlines")
    if not fits:  # the candidates stay in ``alternatives``; they were not fitted on Canny outlines
        return Placement(name, None, False, [], float("nan"), [], "no image outline found along the best candidate",
                         time.perf_counter() - t0, cands[0].scores, alternatives)
    fits.sort(key=lambda f: f[0].objective_mm)
    first, start = fits[0][0], fits[0][2]
    res, splines = fits[0][:2]
    if max(_pose_change(mesh, start, first.pose)) > SETTLED:
        # the outline was segmented along a pose that then moved: once more along the fit
        res, splines = _fit(images, views, mesh, first.pose, steps) or fits[0][:2]
    iou, edge = _assess(images, views, mesh, lib, maps=maps, res=res, splines=splines, hidden=steps.hidden)
    reason = _verdict(res, iou, edge, views, maps)
    if not reason and len(fits) > 1:
        other, other_splines, _ = fits[1]
        apart = _angle_deg(rotation_matrix(*first.pose[3:]), rotation_matrix(*other.pose[3:]))
        if (apart > 20.0 and _objective_px(other, views, maps) - _objective_px(first, views, maps) < CLEAR_OBJECTIVE_PX
                and not _verdict(other, *_assess(images, views, mesh, lib, maps=maps, res=other,
                                                 splines=other_splines, hidden=steps.hidden),
                                 views, maps)):
            reason = f"two orientations {apart:.0f}° apart fit equally well"
    steps.report(1.0, f"{name}: done")
    return Placement(name, res.pose, not reason, iou, float(res.objective_mm), list(res.per_view_mean_mm),
                     reason, time.perf_counter() - t0, edge, alternatives)


class _Rounds:
    """Position hypotheses, in two rounds: pairs of dark-region centroids; then (worked out
    only when a component was not found in the first) pairs that use depth peaks of dark
    regions too, less the first round's."""

    def __init__(self, images, views, fovs):
        self.images, self.views, self.fovs = images, views, fovs
        self._rounds: list[list[np.ndarray]] = []
        self._levels: list = []  # per view: its dark regions (shape_search.dark_levels), for both rounds

    def __len__(self) -> int:
        return 2

    def __getitem__(self, k: int) -> list[np.ndarray]:
        if k >= 2:
            raise IndexError(k)
        while len(self._rounds) <= k:
            peaks = bool(self._rounds)
            if not self._levels:
                self._levels = [ss.dark_levels(image, fov) for image, fov in zip(self.images, self.fovs)]
            points = [ss.dark_region_points(image, fov, max_peaks=4 if peaks else 0, levels=levels)
                      for image, fov, levels in zip(self.images, self.fovs, self._levels)]
            hyps = ss.position_hypotheses(self.views, [c + p for c, p in points], merge_mm=12.0)
            if peaks:
                hyps = [h for h in hyps if all(np.linalg.norm(h - g) > 12.0 for g in self._rounds[0])]
            self._rounds.append(hyps)
        return self._rounds[k]


def _near(lib, views, maps, mesh, *, pose, steps: _Steps, span: float) -> list[_Candidate]:
    """The candidates about a predicted ``pose``: orientations within ``NEAR_DEG``, 64 px either way."""
    pose = np.asarray(pose, float)
    R0 = rotation_matrix(*pose[3:])
    centre = R0 @ mesh.centroid + pose[:3]
    return _candidates(lib, views, maps, [centre], rotations=near_rotations(R0), shifts=ss.shift_grid(64, 16), keep=4,
                       steps=steps, at=0.0, span=span)


def near_candidates(images: Sequence[np.ndarray], views: Sequence[View], mesh: PreparedMesh, pose,
                    *, cancel: Callable[[], bool] | None = None) -> list[np.ndarray]:
    """Tracking recovery's search near a predicted ``pose``: the poses ``find_components``
    would fit on Canny outlines (the best candidate whose edges fit, and a runner-up within
    ``CLOSE_SCORE``), best first, without that fit and its verdict - recovery matches from
    each and judges the match itself, so the fit would be made twice. Empty when nothing
    near fits its outline. Raises ValueError unless there are two images and two views."""
    if len(images) != 2 or len(views) != 2:
        raise ValueError("finding implants needs two images and two views")
    steps = _Steps(None, cancel, 1)
    maps = ss.edge_maps_of(images)[1]
    cands = [c for c in _near(ss.shape_library(mesh), views, maps, mesh, pose=pose, steps=steps, span=1.0)
             if c.score >= MIN_CANDIDATE_SCORE and min(c.scores) >= MIN_EDGE_SCORE]
    return [c.pose(mesh) for c in cands[:2] if c.score >= cands[0].score - CLOSE_SCORE]


def _find_one(name, mesh, images, views, *, maps, rounds, near_pose, steps: _Steps, occupied) -> Placement:
    """Near a predicted pose, or from the position hypotheses: ``rounds`` are lists of
    hypotheses tried in turn until the component is found; hypotheses closer than half
    the summed radii to an ``occupied`` (centroid, radius) of a component already found
    are skipped (a tibial outline half fits a femoral component's edges)."""
    t0 = time.perf_counter()
    lib = ss.shape_library(mesh)
    if near_pose is not None:
        cands = _near(lib, views, maps, mesh, pose=near_pose, steps=steps, span=0.5)
        return _conclude(name, mesh, lib, images, views=views, maps=maps, cands=cands, steps=steps, t0=t0,
                         where=" near the predicted pose")
    best, seen = None, False
    for r, hypotheses in enumerate(rounds):
        seen = seen or bool(hypotheses)
        hypotheses = [h for h in hypotheses
                      if all(np.linalg.norm(h - c) > 0.5 * (radius + mesh.radius) for c, radius in occupied)]
        if not hypotheses:
            continue
        steps.span = (0.0, 0.7) if r == 0 else (0.7, 1.0)
        centres = _rank_hypotheses(lib, views, maps, hypotheses, steps=steps, at=0.0, span=0.25)
        cands = _candidates(lib, views, maps, centres, rotations=_grid(4000), shifts=ss.shift_grid(48, 16), keep=KEEP,
                            steps=steps, at=0.25, span=0.35)
        placement = _conclude(name, mesh, lib, images, views=views, maps=maps, cands=cands, steps=steps, t0=t0,
                              where=" in the images")
        if placement.found:
            return placement
        closer = best is not None and placement.pose is not None and (
            best.pose is None or placement.objective_mm < best.objective_mm)
        if best is None or closer:
            best = placement
    steps.span = (0.0, 1.0)
    if best is None:
        why = "no dark region other than the components found" if seen else "no dark region seen in both views"
        return Placement(name, None, False, [], float("nan"), [], why, time.perf_counter() - t0)
    best.seconds = time.perf_counter() - t0
    return best


def find_components(images: Sequence[np.ndarray], views: Sequence[View], meshes: dict[str, PreparedMesh], *,
                    near: dict[str, np.ndarray] | None = None, progress: ProgressFn | None = None,
                    cancel: Callable[[], bool] | None = None) -> dict[str, Placement]:
    """Locate every component in an image pair with no start pose (*find implants*).

    Dark regions propose positions, thousands of orientations are scored on oriented edge
    maps, the best candidates are refined on the image edges and matched on Canny
    outlines, and each is judged; see the methods page *Find implants*. Positions where a
    component was already found are skipped for the next one.

    Parameters
    ----------
    images : sequence of 2 numpy.ndarray
        The frame's images, float in [0, 1].
    views : sequence of 2 View
        Their calibrated views.
    meshes : dict of str to PreparedMesh
        Component name to its prepared mesh.
    near : dict of str to array_like, optional
        Component name to a predicted pose: search only near it (tracking's recovery).
    progress : callable, optional
        ``progress(fraction, text)`` as it goes.
    cancel : callable, optional
        Polled; when it returns True the search stops.

    Returns
    -------
    dict of str to Placement
        Every component's placement; ``found`` says which are confident.

    Raises
    ------
    ValueError
        Not exactly two images and two views.
    fluorogui.core.cancel.Cancelled
        ``cancel()`` turned true.

    Examples
    --------
    The demo's femoral component, found with no start (seconds per component):

    >>> from fluorogui import Session
    >>> from fluorogui.simulation.demo import demo_project_path
    >>> session = Session.open(demo_project_path("cache", frames=2, image_size=256))
    >>> found = find_components(session.images(0), session.views, {"femoral": session.mesh("femoral")})
    >>> found["femoral"].found, found["femoral"].reason
    (True, '')
    """
    if len(images) != 2 or len(views) != 2:
        raise ValueError("finding implants needs two images and two views")
    near = near or {}
    steps = _Steps(progress, cancel, len(meshes))
    if progress is not None:
        progress(0.0, "preparing the images")
    fovs, maps = ss.edge_maps_of(images)
    rounds = _Rounds(images, views, fovs) if any(name not in near for name in meshes) else []
    steps.check()
    out: dict[str, Placement] = {}
    occupied = []
    found_meshes: list = []  # (mesh, R, t) of the components found, masked for the others

    def search(name, mesh):
        steps.name = name
        seen = maps
        if found_meshes:
            steps.hidden = [projected_region(view, found_meshes, HIDE_MARGIN_PX) for view in views]
            seen = [m.with_hidden(h, MIN_EDGE_SCORE) for m, h in zip(maps, steps.hidden)]
        out[name] = p = _find_one(name, mesh, images, views, maps=seen, rounds=rounds, near_pose=near.get(name),
                                  steps=steps, occupied=occupied)
        if found_meshes and not p.found:
            # the masked pixels score a middling edge for free, so positions beside the others
            # can outrank the component's own (the real tray at mid flexion: 40 mm off, 75-85
            # deg turned): its edges are scored once more unmasked, the others still left out
            # of its fit and verdict
            plain = _find_one(name, mesh, images, views, maps=maps, rounds=rounds, near_pose=near.get(name),
                              steps=steps, occupied=occupied)
            if plain.found or (plain.pose is not None and (p.pose is None or plain.objective_mm < p.objective_mm)):
                out[name] = p = plain
        steps.hidden = None
        if p.found:
            R = rotation_matrix(*p.pose[3:])
            occupied.append((R @ mesh.centroid + p.pose[:3], mesh.radius))
            found_meshes.append((mesh, R, p.pose[:3]))

    for name, mesh in meshes.items():
        search(name, mesh)
        steps.k += 1
    # a component the others hid: searched again with those found masked out of its outline,
    # its fit and its verdict (the overlap is judged on what the others leave free)
    again = [name for name in meshes if not out[name].found]
    if again and found_meshes and len(again) < len(meshes):
        for name in again:
            first = out[name]
            search(name, meshes[name])
            if not out[name].found and first.pose is not None and out[name].pose is None:
                out[name] = first  # keep the closer miss to report
    # none found (each hid the other): the surer miss is held where it fitted best and masked
    # for the others; whichever is then found masks it in turn, and it is searched once more
    surer = _surer_miss(out) if not found_meshes and len(meshes) > 1 else None
    if surer is not None:
        held = out[surer]
        found_meshes.append((meshes[surer], rotation_matrix(*held.pose[3:]), held.pose[:3]))
        for name in meshes:
            if name != surer:
                first = out[name]
                search(name, meshes[name])
                if not out[name].found and first.pose is not None and out[name].pose is None:
                    out[name] = first
        found_meshes.pop(0)
        if found_meshes:
            search(surer, meshes[surer])
            if not out[surer].found and out[surer].pose is None:
                out[surer] = held
    if progress is not None:
        progress(1.0, "done")
    return out


#: a miss whose fit reached at least this overlap in every view is held for the others' search
SURER_MIN_IOU = 0.85


def _surer_miss(out: dict[str, "Placement"]) -> str | None:
    """Of components none of which was found, the one whose closest miss fits best (the
    highest lowest-view overlap, at least ``SURER_MIN_IOU``); None when none comes close."""
    misses = [(min(p.iou), name) for name, p in out.items() if p.pose is not None and p.iou]
    misses = [m for m in misses if m[0] >= SURER_MIN_IOU]
    return max(misses)[1] if misses else None
