"""Time to compute contact kinematics (``workflow.contact``) on the real biplane data.

The poses are a tracked project's (``--project P.fluoro``, made with ``fluorogui import
../shared/data/biplane-tka --out P.fluoro`` then ``fluorogui track P.fluoro``) or, by
default, the reference poses in ``tests/data/biplane_reference_poses.csv``; the meshes are
the real femoral and tibial components. Times, each the fastest of ``--repeat`` runs:

- the set-up (the femoral surface split into condyles, normals, the default frames);
- every frame with both poses, then the same poses repeated to ``--frames`` (261) frames:
  the lowest points only, and with an insert (the real data has none: the tibial
  component itself stands in for it, ~30,000 triangles, so the gaps are to the metal tray);
- with ``--project``, the session's own contact rows (``workflow.contact.contact_rows``: its
  statuses; the pivot over matched frames only);
- ``--figure OUT.png`` draws the contact plot of the frames (``workflow.contact_plot``).

Usage: .venv/bin/python benchmarks/bench_contact.py [--project P.fluoro] [--frames 261]
       [--repeat 3] [--figure contact.png]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fluorogui.core.knee.anatomy import default_frame  # noqa: E402
from fluorogui.io.meshes.read import load_mesh  # noqa: E402
from fluorogui.io.pose_files import read_long_poses  # noqa: E402
from fluorogui.workflow.contact import contact_of_poses, contact_setup, pivot_of_rows  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "biplane-tka"
REFERENCE = ROOT / "tests" / "data" / "biplane_reference_poses.csv"


def project_poses(path: Path) -> tuple[dict, str, str]:
    """The matched and reviewed-or-not poses of a project's frames with both components."""
    from fluorogui.workflow import Session

    session = Session.open(path)
    poses = {}
    for row in session.knee_rows():
        if row.status != "missing":
            for c in ("femoral", "tibial"):
                poses[(row.frame, c)] = np.asarray(row.records[c].pose, dtype=float)
    statuses = [r.status for r in session.knee_rows()]
    summary = ", ".join(f"{statuses.count(s)} {s}" for s in ("matched", "needs_review", "missing"))
    return poses, session.side or "right", f"{path.name} ({summary})"


def repeated(poses: dict, count: int) -> dict:
    frames = sorted({f for f, _ in poses})
    out = {}
    for k in range(count):
        f = frames[k % len(frames)]
        for c in ("femoral", "tibial"):
            out[(k, c)] = poses[(f, c)]
    return out


def fastest(repeat: int, run):
    best, result = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = run()
        best = min(best, time.perf_counter() - t0)
    return best, result


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--project", type=Path)
    p.add_argument("--frames", type=int, default=261)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--figure", type=Path)
    args = p.parse_args(argv)
    if not DATA.is_dir():
        print(f"bench_contact: no real data at {DATA}", file=sys.stderr)
        return 2
    if args.project:
        poses, side, source = project_poses(args.project)
    else:
        all_poses = read_long_poses(REFERENCE)
        poses = {k: v for k, v in all_poses.items()
                 if all((k[0], c) in all_poses for c in ("femoral", "tibial"))}
        side, source = "right", REFERENCE.name
    femur = load_mesh(DATA / "models" / "femoral_component.stl")
    tibia = load_mesh(DATA / "models" / "tibial_component.stl")
    frames = {c: default_frame(c, *m) for c, m in (("femoral", femur), ("tibial", tibia))}
    count = len({f for f, _ in poses})
    print(f"poses: {source}: {count} frames with both poses; femoral mesh {len(femur[1]):,} triangles, "
          f"stand-in insert (the tibial component) {len(tibia[1]):,}")

    def setup(insert=None):
        return contact_setup(femur, femoral_frame=frames["femoral"], tibial_frame=frames["tibial"], side=side,
                             insert_mesh=insert)

    for label, insert in (("lowest points", None), ("lowest points and gaps to the insert", tibia)):
        t_setup, prepared = fastest(args.repeat, lambda insert=insert: setup(insert))
        print(f"{label}: set-up {t_setup:.2f} s")
        for n, chosen in ((count, poses), (args.frames, repeated(poses, args.frames))):
            t, rows = fastest(args.repeat, lambda chosen=chosen, prepared=prepared:
                              contact_of_poses(chosen, prepared, frames["femoral"]))
            print(f"  {n} frames: {t:.2f} s ({1000 * t / n:.1f} ms a frame)")
            if insert is None and n == count:
                found = pivot_of_rows(rows)
                print(f"  pivot: x {found.x_mm:.2f} mm, y {found.y_mm:.2f} mm, {found.kind}, "
                      f"{found.frames_used} frames used")
    if args.project:  # the session's own rows: its statuses, the pivot over matched frames only
        from fluorogui.workflow import Session
        from fluorogui.workflow.contact import contact_rows

        rows = contact_rows(Session.open(args.project))
        found = pivot_of_rows(rows)
        print(f"project's matched frames: pivot x {found.x_mm:.2f} mm, y {found.y_mm:.2f} mm, {found.kind}, "
              f"{found.frames_used} frames used, {found.frames_ignored} left out")
    else:
        rows = contact_of_poses(poses, setup(), frames["femoral"])
    if args.figure:
        from fluorogui.workflow.contact_plot import save_contact_figure

        save_contact_figure(rows, args.figure, side=side, title=source.split(" (")[0], pivot=pivot_of_rows(rows))
        print(f"wrote {args.figure}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
