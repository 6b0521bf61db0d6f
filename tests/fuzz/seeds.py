"""Small valid files of every format a loader reads: the seeds the fuzz runs mutate."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

FIXTURES = Path(__file__).resolve().parents[1] / "io" / "data"

MAYACAM2 = """image size
64,48
camera matrix
1200,0,32
0,1200,24
0,0,1
rotation
1,0,0
0,1,0
0,0,1
translation
0,0,1000
"""
MAYACAM1 = "0,0,1000\n0,0,0\n0,0,0\n33,25,-1200\n1,64,48\n"
JOINTTRACK = "JT_INTCALIB\n1200\n0\n0\n0.4\n"


def make_seeds(folder: Path) -> dict[str, list[Path]]:
    """Write the seed files into ``folder``; loader name -> files."""
    import pyvista as pv

    from fluorogui.core.projection.geometry import View
    from fluorogui.io.calibration import save_view_json
    from fluorogui.io.images import write_image

    folder.mkdir(parents=True, exist_ok=True)
    seeds: dict[str, list[Path]] = {k: [] for k in ("calibration", "image", "mesh", "outline", "pairs",
                                                    "reference", "project")}
    for name, text in (("mayacam2.txt", MAYACAM2), ("mayacam1.txt", MAYACAM1), ("jointtrack.txt", JOINTTRACK)):
        (folder / name).write_text(text)
        seeds["calibration"].append(folder / name)
    view = View.looking_at((0, -1000, 0), (0, 0, 0), (0, 0, 1), 1200, image_size=(64, 48), pitch=0.4, name="a")
    save_view_json(view, folder / "cal.json")
    seeds["calibration"].append(folder / "cal.json")
    image = np.linspace(0, 1, 64 * 48).reshape(48, 64)
    for name, bits in (("img.png", 8), ("img16.png", 16), ("img.tif", 16)):
        write_image(folder / name, image, bits=bits)
        seeds["image"].append(folder / name)
    ball = pv.Sphere(radius=20.0, theta_resolution=8, phi_resolution=8)
    for name, binary in (("ball.ply", False), ("ballb.ply", True), ("ball.stl", True), ("balla.stl", False),
                         ("ball.vtk", False), ("ball.obj", None)):
        ball.save(folder / name, **({} if binary is None else {"binary": binary}))
        seeds["mesh"].append(folder / name)
    (folder / "outline.csv").write_text("u,v\n" + "".join(f"{10 + i},{20 + i % 5}\n" for i in range(20)))
    seeds["outline"].append(folder / "outline.csv")
    (folder / "pairs.csv").write_text("frame,cam1,cam2\n0,img.png,img16.png\n1,img.png,img.tif\n")
    seeds["pairs"].append(folder / "pairs.csv")
    (folder / "ref.csv").write_text("frame,component,x,y,z,alpha,beta,gamma\n0,femoral,1,2,3,4,5,6\n"
                                    "1,tibial,-1,-2,-3,-4,-5,-6.5\n")
    seeds["reference"].append(folder / "ref.csv")
    for name in ("project_v1.fluoro", "project_v2.fluoro"):
        shutil.copy(FIXTURES / name, folder / name)
        seeds["project"].append(folder / name)
    return seeds
