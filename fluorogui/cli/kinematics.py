"""``fluorogui kinematics``: knee kinematics (Grood & Suntay) of a bare poses CSV from any tool."""
from __future__ import annotations

import json
import sys
from pathlib import Path

from fluorogui.cli.common import UsageError, warn
from fluorogui.cli.export import frame_list


def add_parser(sub):
    k = sub.add_parser("kinematics", help="knee kinematics (Grood & Suntay) of poses from anywhere")
    k.add_argument("--poses", required=True, metavar="POSES.csv",
                   help="columns frame,component,x,y,z,alpha,beta,gamma (component femoral or tibial)")
    k.add_argument("--side", required=True, choices=("right", "left"))
    k.add_argument("--femoral-frame", metavar="F.json", help='{"matrix": [[4 rows of 4]]}, anatomical -> model')
    k.add_argument("--tibial-frame", metavar="T.json")
    k.add_argument("--femoral-mesh", metavar="MESH", help="for the default femoral frame")
    k.add_argument("--tibial-mesh", metavar="MESH", help="for the default tibial frame")
    k.add_argument("--out", required=True, metavar="OUT.csv")
    return k


def load_frame_json(path) -> "object":
    """A frame JSON ``{"matrix": [[4 rows of 4]]}`` (anatomical → model), checked."""
    from fluorogui.core.knee.kinematics import KinematicsError, check_frame
    from fluorogui.io.errors import InputError
    from fluorogui.io.pose_files import read_text_lines

    path = Path(path)
    text = "\n".join(read_text_lines(path))
    try:
        document = json.loads(text)
    except (json.JSONDecodeError, RecursionError) as exc:
        raise InputError(path, f"is not JSON ({getattr(exc, 'msg', 'too deeply nested')})") from None
    if not isinstance(document, dict) or "matrix" not in document:
        raise InputError(path, 'must be {"matrix": [[4 rows of 4 numbers]]}')
    try:
        return check_frame(document["matrix"])
    except KinematicsError as exc:
        raise InputError(path, f"'matrix': {exc}") from None


def run(args) -> int:
    from fluorogui import __version__
    from fluorogui.core.knee.anatomy import default_frame
    from fluorogui.core.knee.kinematics import KINEMATICS_COLUMNS, SIGN_CONVENTIONS, KinematicsError
    from fluorogui.io.errors import InputError
    from fluorogui.io.files import check_output_file
    from fluorogui.io.meshes.read import load_mesh
    from fluorogui.io.pose_files import read_long_poses, write_csv
    from fluorogui.workflow.exports import kinematics_of_poses

    out = check_output_file(args.out)
    frames = {}
    for component, frame_path, mesh_path in (("femoral", args.femoral_frame, args.femoral_mesh),
                                             ("tibial", args.tibial_frame, args.tibial_mesh)):
        if frame_path:
            frames[component] = load_frame_json(frame_path)
        elif mesh_path:
            vertices, faces = load_mesh(mesh_path)
            try:
                frames[component] = default_frame(component, vertices, faces)
            except KinematicsError as exc:
                raise InputError(mesh_path, f"no default anatomical frame: {exc}") from None
        else:
            raise UsageError(f"fluorogui: kinematics: give --{component}-frame or --{component}-mesh "
                             f"(the default {component} frame comes from the mesh)")
    poses = read_long_poses(args.poses)
    rows = kinematics_of_poses(poses, args.side, frames["femoral"], frames["tibial"])
    header = [f"fluorogui {__version__} knee kinematics of {Path(args.poses).name}",
              f"side: {args.side}", "units: mm and degrees", f"kinematics: {SIGN_CONVENTIONS}"]
    for component, matrix in frames.items():
        header.append(f"{component} anatomical frame (anatomical -> model): {json.dumps(matrix.round(9).tolist())}")
    header += [f"frame {frame}: NaN: {reason}" for frame, _, reason in rows if reason]
    write_csv(out, header, ["frame", *KINEMATICS_COLUMNS],
              [[frame, *(float(v) for v in values.values())] for frame, values, _ in rows])
    nan_rows = [frame for frame, _, reason in rows if reason]
    if nan_rows:
        warn(f"{len(nan_rows)} frame{'s' if len(nan_rows) > 1 else ''} written as NaN "
             f"({next(r for _, _, r in rows if r)}{', …' if len(nan_rows) > 1 else ''}): {frame_list(nan_rows)}")
    print(f"wrote {out} ({len(rows)} frames)", file=sys.stdout)
    return 0
