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
