"""How often each quality check flags a right pose: the flags' precision, per check.

``flag_precision(results, right)`` takes tracking results (``FrameResult``) and a function
that says whether a pose is right (against the truth of a generated sequence, or against
the reference poses of the real one; None where nothing tells). Per check named in the
results' ``failed`` lists, it counts the frames flagged with it and how many of those were
right poses anyway; over all flagged frames, the share that was right (target: under one
in five); and the frames shown as matched that were wrong (target: none). Used by
``bench_tracking.py`` for ``synthetic`` (``--xray``), ``partial`` and ``real``.
"""
from __future__ import annotations

from collections import Counter
from typing import Callable, Iterable


def flag_precision(results: Iterable, right: Callable[[object], bool | None], label: str = "") -> dict:
    """Per check: flagged frames and right poses among them; print one line each."""
    flagged, flagged_right, judged = Counter(), Counter(), Counter()
    total = total_right = total_judged = wrong_matched = 0
    for r in results:
        verdict = right(r) if r.pose is not None else None
        if r.status == "matched":
            wrong_matched += verdict is False
            continue
        total += 1
        total_judged += verdict is not None
        total_right += bool(verdict)
        for check in set(r.failed or ["(none named)"]):
            flagged[check] += 1
            judged[check] += verdict is not None
            flagged_right[check] += bool(verdict)
    share = total_right / total_judged if total_judged else float("nan")
    print(f"  flag precision{(' ' + label) if label else ''}: {total} flagged, {total_right} of the "
          f"{total_judged} with a known answer right poses ({100 * share:.0f} %, target under 20 %); "
          f"wrong poses shown as matched: {wrong_matched} (target 0)")
    for check in sorted(flagged):
        print(f"    {check:16s} flagged {flagged[check]:3d}, right poses {flagged_right[check]:3d} "
              f"of {judged[check]} with a known answer")
    return {"flagged": total, "flagged_right": total_right, "flagged_judged": total_judged,
            "right_share": share, "wrong_matched": wrong_matched,
            "per_check": {c: {"flagged": flagged[c], "right": flagged_right[c], "judged": judged[c]}
                          for c in flagged}}


def region_fit_verdict(session, result, matched_poses: dict, tolerance: float = 0.5) -> bool | None:
    """Is a real frame's pose right, where no reference pose is stored? Judged by the
    independent region fit (``fluorogui.reference.region_fit``: pixels beyond the field of
    view and the other component's region, at its pose in ``matched_poses`` or the result's
    own, left out): right when the fit from the pose lands within ``tolerance`` mm / deg
    (largest translation difference, rotation angle); not right when the fit is refused and
    the pose's own region overlaps the dark region under ``MIN_IOU`` in a view; else None."""
    import numpy as np

    from fluorogui.reference.region_fit import (
        MIN_IOU,
        EdgeMesh,
        LowOverlap,
        component_masks,
        field_of_view,
        fit_pose,
        overlap_at,
        rotation_angle,
    )

    def edges(component):
        mesh = session.mesh(component)
        return EdgeMesh.from_arrays(mesh.vertices, mesh.faces)

    pose = np.asarray(result.pose, dtype=float)
    other = "tibial" if result.component == "femoral" else "femoral"
    images = session.images(result.frame)
    fields = [field_of_view(im) for im in images]
    at_other = matched_poses.get((result.frame, other))
    exclude = component_masks(session.views, edges(other), at_other) if at_other is not None else None
    mesh = edges(result.component)
    try:
        fit = fit_pose(session.views, images, mesh, pose, exclude=exclude, fields=fields)
    except LowOverlap:
        return False if min(overlap_at(session.views, images, mesh, pose, exclude=exclude,
                                       fields=fields)) < MIN_IOU else None
    return bool(np.abs(fit.pose[:3] - pose[:3]).max() <= tolerance and rotation_angle(fit.pose, pose) <= tolerance)
