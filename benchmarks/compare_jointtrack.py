"""Single-plane check: fluorogui's poses against JointTrack's own on data/single-plane-tka.

The folder is imported as a single-plane session (``fluorogui.io.importer.import_folder``)
and every component of every frame is matched through the workflow (``Session.match``)
from JointTrack's pose (``fem.jts``, ``tib.jts``, converted by ``jointtrack_to_pose``) and
from ``--starts`` starts perturbed by up to ``--perturb-mm`` / ``--perturb-deg`` (uniform).
It prints, per component and frame, the difference (fluorogui - JointTrack) per degree of
freedom in JointTrack's camera frame (x, y in the image plane, z along the beam: the weak
direction) and the spread (SD) of the perturbed starts, then the mean and SD over frames;
last, the knee kinematics of JointTrack's own poses with the meshes' default anatomical frames.

Usage: .venv/bin/python benchmarks/compare_jointtrack.py [--data DIR] [--starts 5]
           [--perturb-mm 2] [--perturb-deg 2] [--seed 0]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from fluorogui.io.calibration import jointtrack_to_pose, load_jointtrack_poses
from fluorogui.io.importer import import_folder
from fluorogui.workflow.messages import SINGLE_PLANE_NOTE
from fluorogui.workflow.session import Session

LABELS = ("x", "y", "z", "alpha", "beta", "gamma")
POSE_FILES = {"femoral": "fem.jts", "tibial": "tib.jts"}


def matched_pose(session: Session, component: str, frame: int, start) -> tuple[np.ndarray, str]:
    session.set_pose(component, frame, start)
    session.match(frame, component)
    record = session.project.poses[(frame, component)]
    return record.pose.copy(), record.status


def main(argv=None) -> int:
    default = Path(__file__).resolve().parents[2] / "shared" / "data" / "single-plane-tka"
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=default)
    parser.add_argument("--starts", type=int, default=5)
    parser.add_argument("--perturb-mm", type=float, default=2.0)
    parser.add_argument("--perturb-deg", type=float, default=2.0)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if not args.data.is_dir():
        print(f"{args.data}: data folder not found", file=sys.stderr)
        return 2
    session = Session(import_folder(args.data))
    rng = np.random.default_rng(args.seed)
    print(f"note: {SINGLE_PLANE_NOTE}")
    print("difference fluorogui - JointTrack (mm, deg); spread = SD over perturbed starts")
    for component in session.components():
        reference_rows = load_jointtrack_poses(args.data / POSE_FILES[component])
        differences, spreads = [], []
        print(f"\n{component}: frame status  " + "  ".join(f"{label:>7}" for label in LABELS) + "   | spread "
              + " ".join(f"{label:>6}" for label in LABELS))
        for index, frame in enumerate(session.frames):
            reference = jointtrack_to_pose(reference_rows[index])
            pose, status = matched_pose(session, component, frame, reference)
            others = []
            for _ in range(args.starts):
                step = np.concatenate([rng.uniform(-args.perturb_mm, args.perturb_mm, 3),
                                       rng.uniform(-args.perturb_deg, args.perturb_deg, 3)])
                others.append(matched_pose(session, component, frame, reference + step)[0])
            spread = np.std(np.array(others), axis=0, ddof=1) if len(others) > 1 else np.zeros(6)
            differences.append(pose - reference)
            spreads.append(spread)
            print(f"{'':9}{frame:5d} {status:8}" + "  ".join(f"{d:7.2f}" for d in pose - reference)
                  + "   |        " + " ".join(f"{s:6.2f}" for s in spread))
        d = np.array(differences)
        print(f"{'':9}mean          " + "  ".join(f"{v:7.2f}" for v in d.mean(axis=0)))
        print(f"{'':9}SD            " + "  ".join(f"{v:7.2f}" for v in d.std(axis=0, ddof=1)))
    print_jointtrack_kinematics(session, args.data)
    return 0


def print_jointtrack_kinematics(session: Session, data: Path) -> None:
    """The knee kinematics of JointTrack's own poses with the default anatomical frames of
    the meshes (right knee): a check that those frames hold on this second design."""
    from fluorogui.core.knee.kinematics import KINEMATICS_COLUMNS
    from fluorogui.workflow.exports import kinematics_of_poses

    if set(POSE_FILES) - set(session.components()):
        return
    poses = {(frame, c): jointtrack_to_pose(row) for c, name in POSE_FILES.items()
             for frame, row in zip(session.frames, load_jointtrack_poses(data / name))}
    rows = kinematics_of_poses(poses, "right", session.default_anatomical_frame("femoral"),
                               session.default_anatomical_frame("tibial"))
    print("\nknee kinematics of JointTrack's poses (default anatomical frames, right knee):")
    print(f"{'':9}frame " + " ".join(f"{c:>14}" for c in KINEMATICS_COLUMNS))
    for frame, values, _ in rows:
        print(f"{'':9}{frame:5d} " + " ".join(f"{v:14.2f}" for v in values.values()))


if __name__ == "__main__":
    sys.exit(main())
