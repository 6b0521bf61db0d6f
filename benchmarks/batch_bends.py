"""Two generated knee bends through ``fluorogui batch``, every frame scored against its truth.

``batch_bends(folder, frames, ...)`` draws two bends of the real meshes (seeds 1 and 2:
the same motion and views, other noise) under ``folder`` (``bend1``, ``bend2``), with the
silhouette images of ``fluorogui.simulation.knee_bend`` or, ``xray=True``, the independent
X-ray model (``xray_bend.xray_bends``: the seeds share the Beer-Lambert path lengths, so the
second bend costs its noise only). A folder that already holds both bends, drawn alike, is
used again: each project is put back as drawn (``knee_bend.fluoro.drawn``) before the run.
Then ``fluorogui batch BEND1 BEND2 --workers N``; prints the exit code, per frame and
component the status and the error against the truth (largest translation mm, largest
angle deg, body-fixed ``pose_error``), the RMS per component over the matched frames and
the reasons of whatever was not matched. Used by ``bench_tracking.py batch``.
"""
from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
COMPONENTS = ("femoral", "tibial")
SEEDS = (1, 2)


def _drawn(folder: Path, frames: int, xray: bool, overlap_at_start: bool) -> list[Path] | None:
    """The bends already drawn in ``folder`` as asked, put back as drawn; else None."""
    recipe = {"frames": frames, "xray": xray, "overlap_at_start": overlap_at_start}
    paths = [folder / f"bend{s}" / "knee_bend.fluoro" for s in SEEDS]
    marker = folder / "drawn.json"
    if not marker.is_file() or json.loads(marker.read_text()) != recipe:
        return None
    if not all(p.with_name(p.name + ".drawn").is_file() for p in paths):
        return None
    for p in paths:
        shutil.copyfile(p.with_name(p.name + ".drawn"), p)
    return paths


def _draw(folder: Path, frames: int, xray: bool, overlap_at_start: bool, workers: int) -> list[Path]:
    from fluorogui.simulation.knee_bend import build_knee_sequence

    folders = [folder / f"bend{s}" for s in SEEDS]
    if xray:
        from xray_bend import xray_bends

        paths = xray_bends(folders, frames, seeds=list(SEEDS), overlap_at_start=overlap_at_start, workers=workers)
    else:
        models = ROOT.parent / "shared" / "data" / "biplane-tka" / "models"
        paths = [build_knee_sequence(f, models / "femoral_component.stl", models / "tibial_component.stl",
                                     frames=frames, seed=s, workers=workers, overlap_at_start=overlap_at_start)
                 for f, s in zip(folders, SEEDS)]
    for p in paths:
        shutil.copyfile(p, p.with_name(p.name + ".drawn"))
    (folder / "drawn.json").write_text(json.dumps({"frames": frames, "xray": xray,
                                                   "overlap_at_start": overlap_at_start}))
    return paths


def batch_bends(folder: Path, frames: int, *, xray: bool = False, overlap_at_start: bool = False,
                workers: int = 2) -> dict:
    """Draw (or reuse) the two bends, run ``fluorogui batch`` on them, score every frame."""
    from fluorogui import Session
    from fluorogui.cli import main as cli_main
    from fluorogui.core.projection.pose import pose_error

    folder = Path(folder)
    t0 = time.perf_counter()
    paths = _drawn(folder, frames, xray, overlap_at_start)
    reused = paths is not None
    if paths is None:
        paths = _draw(folder, frames, xray, overlap_at_start, workers)
    drawn_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    code = cli_main(["batch", *map(str, paths), "--workers", str(workers)])
    wall = time.perf_counter() - t0
    out = {"exit_code": code, "wall_seconds": wall, "drawn_seconds": drawn_s, "frames": 2 * frames,
           "not_matched": 0, "wrong_matched": 0, "rows": []}
    errors = {c: [] for c in COMPONENTS}
    for path in paths:
        session = Session.open(path)
        truth = session.project.settings["truth"]
        for frame in session.frames:
            for c in COMPONENTS:
                record = session.pose_record(c, frame)
                row = {"bend": path.parent.name, "frame": frame, "component": c,
                       "status": str(record.status) if record else "no result",
                       "reason": record.reason if record else ""}
                if record is not None:
                    e = pose_error(record.pose, np.asarray(truth[str(frame)][c]))
                    row.update(mm=float(np.abs(e[:3]).max()), deg=float(np.abs(e[3:]).max()), error=e.tolist())
                    if record.status == "matched":
                        errors[c].append(e)
                        out["wrong_matched"] += row["mm"] > 1.0 or row["deg"] > 1.0
                out["not_matched"] += row["status"] != "matched"
                out["rows"].append(row)
    print(f"batch: 2 generated bends x {frames} frames x 2 components ({'X-ray model' if xray else 'silhouette'} "
          f"images{', overlapping most at the start' if overlap_at_start else ''}; "
          f"{'drawn before' if reused else f'drawn in {drawn_s:.0f} s'}), --workers {workers}: exit {code} "
          f"in {wall:.1f} s")
    for row in out["rows"]:
        off = f"{row['mm']:.4f} mm / {row['deg']:.4f} deg" if "mm" in row else "-"
        print(f"  {row['bend']} frame {row['frame']:3d} {row['component']:8s} {row['status']:12s} {off}"
              + (f"  {row['reason']}" if row["status"] != "matched" else ""))
    for c, E in errors.items():
        E = np.array(E).reshape(-1, 6)
        rms = np.sqrt((E ** 2).mean(0)) if len(E) else np.full(6, np.nan)
        out[c] = {"matched": len(E), "rms_mm": float(np.sqrt((E[:, :3] ** 2).mean())) if len(E) else None,
                  "rms_deg": float(np.sqrt((E[:, 3:] ** 2).mean())) if len(E) else None, "rms_per_dof": rms.tolist()}
        print(f"  {c:8s} matched {len(E)}/{2 * frames}: RMS {out[c]['rms_mm'] or np.nan:.4f} mm / "
              f"{out[c]['rms_deg'] or np.nan:.4f} deg (target 0.05 / 0.05); per x y z mm, alpha beta gamma deg "
              + " ".join(f"{v:.4f}" for v in rms))
    print(f"  not matched {out['not_matched']} (target 0); matched but more than 1 mm / 1 deg off "
          f"{out['wrong_matched']} (target 0); exit {code} (target 0)\n")
    return out
