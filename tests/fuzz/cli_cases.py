"""Command lines to throw at ``fluorogui``: bad option values and broken input files.

Each case is ``(argv, expect, names)``: ``expect`` "bad" means the run must be refused (exit
2) with one line containing one of ``names`` (the option or the file); "any" (a mutated file
that may still be valid) means any clean outcome (exit 0, 2 or 3, one line on refusal);
"warned" means a clean run (exit 0) whose stderr warns, naming the file; "bounded" a match
that ends matched or flagged (exit 0 or 3). Every case must end within ``BOUNDED_SECONDS``.

``regression_cases`` are the issues' "messages that name the wrong input": calibrations with
absurd values (refused when read, naming the calibration file, not as a mismatch with the
image), start poses at, behind or far from a source (refused as ``--start``), a lower-case
JointTrack header (read, with a warning); and issue 44's: blank and damaged images, an
outline far off its image, a calibration with a repeated section, Arabic-Indic digits or a
1e308° angle, a one-triangle mesh, ``--start`` with seven numbers or 10^6° angles, and images
listed in a pairs CSV named with it. Given the real data, also the matches that took
minutes (the paper method on automatic outlines, a start 54 mm off), which must be bounded."""
from __future__ import annotations

import os
import random
import shutil
from pathlib import Path

import numpy as np
from loader_worker import mutate

CORPUS = Path(__file__).resolve().parent / "corpus"
BAD_INTS = ["-5", "-1", "99999999999999999999", "abc", "1.5", "", "nan", "1e3"]  # bad for every option
BAD_FLOATS = ["nan", "inf", "-inf", "1e999", "abc", "", "1e8"]
BOUNDED_SECONDS = 30.0  # a match that takes longer is a hang


def make_scene(folder: Path) -> dict:
    """Two calibrations, two 64x48 images, a sphere mesh, two outlines, pairs and poses."""
    import pyvista as pv

    from fluorogui.core.projection.geometry import View
    from fluorogui.io.calibration import save_view_json
    from fluorogui.io.images import write_image
    from fluorogui.io.outlines import write_outline_csv

    folder.mkdir(parents=True, exist_ok=True)
    views = [View.looking_at((0, -1000, 0), (0, 0, 0), (0, 0, 1), 1200, image_size=(64, 48), pitch=0.4, name="a"),
             View.looking_at((1000, 0, 0), (0, 0, 0), (0, 0, 1), 1200, image_size=(64, 48), pitch=0.4, name="b")]
    scene = {}
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    for k, view in enumerate(views):
        save_view_json(view, folder / f"cam{k}.json")
        write_image(folder / f"img{k}.png", np.linspace(0, 1, 64 * 48).reshape(48, 64), bits=8)
        write_outline_csv(folder / f"outline{k}.csv", np.column_stack([32 + 15 * np.cos(t), 24 + 15 * np.sin(t)]))
        scene[f"cam{k}"], scene[f"img{k}"], scene[f"outline{k}"] = (folder / f"cam{k}.json", folder / f"img{k}.png",
                                                                      folder / f"outline{k}.csv")
    pv.Sphere(radius=20.0, theta_resolution=12, phi_resolution=12).save(folder / "ball.stl")
    scene["mesh"] = folder / "ball.stl"
    write_image(folder / "small.png", np.linspace(0, 1, 32 * 32).reshape(32, 32), bits=8)
    (folder / "jt").mkdir(exist_ok=True)  # JointTrack's assumed size:
    write_image(folder / "jt" / "square.png", np.linspace(0, 1, 1024 * 1024).reshape(1024, 1024), bits=8)
    (folder / "pairs.csv").write_text("frame,cam1,cam2\n0,img0.png,img1.png\n")
    (folder / "ref.csv").write_text("frame,component,x,y,z,alpha,beta,gamma\n0,femoral,0,0,0,0,0,0\n")
    scene["pairs"], scene["reference"] = folder / "pairs.csv", folder / "ref.csv"
    scene["folder"] = folder
    return scene


def match_argv(scene: dict, **replace) -> list[str]:
    s = {**scene, **replace}
    return ["match", "--camera", str(s["cam0"]), "--camera", str(s["cam1"]), "--image", str(s["img0"]),
            "--image", str(s["img1"]), "--model", str(s["mesh"]), "--outline", str(s["outline0"]),
            "--outline", str(s["outline1"]), "--start", "0", "0", "0", "0", "0", "0", "--starts", "1"]


def repeat_argv(scene: dict, **replace) -> list[str]:
    s = {**scene, **replace}
    return ["validate", "repeatability", "--camera", str(s["cam0"]), "--camera", str(s["cam1"]),
            "--model", str(s["mesh"]), "--reference", str(s["reference"]), "--pairs", str(s["pairs"]),
            "--component", "femoral", "--starts", "1"]


OPTION_CASES = [  # (argv builder, option, kind)
    (match_argv, "--starts", "1-1000"), (match_argv, "--outline-points", "from-1"), (match_argv, "--points", "from-10"),
    (repeat_argv, "--starts", "1-1000"), (repeat_argv, "--seed", "from-0"), (repeat_argv, "--frames", "from-0"),
    (lambda s: ["track", "x.fluoro"], "--workers", "1-256"), (lambda s: ["batch", "x.fluoro"], "--workers", "from-1"),
    (lambda s: ["bench"], "--starts", "1-1000"),
    (lambda s: ["demo", str(s["folder"] / "d.fluoro")], "--frames", "1-1000"),
]
SLOTS = [("cam0", match_argv), ("img1", match_argv), ("mesh", match_argv), ("outline0", match_argv),
         ("pairs", repeat_argv), ("reference", repeat_argv), ("cam1", repeat_argv)]


def _bad_file(kind: str, slot: str, scene: dict, folder: Path, n: int, rng: random.Random) -> tuple[Path, str]:
    source = Path(scene[slot])
    target = folder / f"case{n}_{kind}{source.suffix}"
    if kind == "missing":
        return target, "bad"
    if kind == "folder":
        target.mkdir()
        return target, "bad"
    if kind == "fifo" and hasattr(os, "mkfifo"):
        os.mkfifo(target)
        return target, "bad"
    if kind == "empty":
        target.write_bytes(b"")
        return target, "bad"
    if kind == "junk":
        target.write_bytes(bytes([0]) + bytes(rng.randrange(256) for _ in range(2000)))
        return target, "bad"
    if kind == "billions" and slot == "mesh":
        shutil.copy(CORPUS / "billions.ply", target.with_suffix(".ply"))
        return target.with_suffix(".ply"), "bad"
    if kind == "wrong_size" and slot.startswith("img"):
        shutil.copy(scene["folder"] / "small.png", target)
        return target, "bad"
    target.write_bytes(mutate(source.read_bytes(), rng))
    return target, "any"


def generate(scene: dict, folder: Path, count: int, seed: int = 0) -> list[tuple[list[str], str, list[str]]]:
    rng = random.Random(seed)
    folder.mkdir(parents=True, exist_ok=True)
    cases = []
    for n in range(count):
        if n % 2 == 0:
            build, option, kind = OPTION_CASES[(n // 2) % len(OPTION_CASES)]
            values = BAD_INTS + {"1-1000": ["0", "1001"], "1-256": ["0", "257"], "from-1": ["0"],
                                 "from-10": ["0", "9"], "from-0": []}[kind]
            value = rng.choice(values)
            argv = build(scene)
            if option in argv:
                argv[argv.index(option) + 1] = value
            else:
                argv += [option, value]
            if build is match_argv and rng.random() < 0.3:  # a bad start value instead
                at = argv.index("--start") + 1 + rng.randrange(6)
                argv[at] = value = rng.choice(BAD_FLOATS)
                option = "--start"
            cases.append((argv, "bad", [option]))
        else:
            slot, build = SLOTS[(n // 2) % len(SLOTS)]
            kind = rng.choice(["missing", "folder", "fifo", "empty", "junk", "billions", "wrong_size",
                               "mutated", "mutated", "mutated"])
            path, expect = _bad_file(kind, slot, scene, folder, n, rng)
            cases.append((build(scene, **{slot: path}), expect, [str(path), path.name]))
    return cases


def regression_cases(scene: dict, folder: Path,
                     real: Path | None = None) -> list[tuple[str, list[str], str, list[str]]]:
    """(name, argv, expect, names) of every case of the issues, built on ``scene`` (and the
    real data in ``real``, when given and present)."""
    from fluorogui.io.calibration import load_view, save_view_mayacam2

    folder.mkdir(parents=True, exist_ok=True)
    save_view_mayacam2(load_view(scene["cam0"]), folder / "good_mayacam2.txt")
    good = (folder / "good_mayacam2.txt").read_text()
    lines = good.splitlines()
    focal, translation = lines[4].split(",")[0], lines[-1]

    def mayacam(name: str, text: str) -> Path:
        (folder / name).write_text(text)
        return folder / name

    calibrations = {
        "width_1e12": mayacam("width.txt", good.replace("64,48", "1000000000000,48", 1)),
        "focal_1e-12": mayacam("focal.txt", good.replace(focal + ",", "1e-12,", 1)),
        "translation_1e300": mayacam("translation.txt", good.replace("\n" + translation, "\n1e300", 1)),
        "underscore_number": mayacam("underscore.txt", good.replace("64,48", "1_000,48", 1)),
        "huge_integer": mayacam("huge.txt", good.replace("64,48", "99999999999999999999999,48", 1)),
        "jointtrack_pitch_1e-300": mayacam("jt_pitch.txt", "JT_INTCALIB\n1200\n0\n0\n1e-300\n"),
        "jointtrack_offset_1e300": mayacam("jt_offset.txt", "JT_INTCALIB\n1200\n1e300\n0\n0.4\n"),
    }
    cases = [(name, match_argv(scene, cam0=path), "bad", [str(path)]) for name, path in calibrations.items()]
    for name, start in (("start_behind_source", ["0", "-1100", "0"]), ("start_at_source", ["0", "-995", "0"]),
                        ("start_half_way_to_source", ["0", "-500", "0"]), ("start_1e5_mm_away", ["0", "100000", "0"])):
        argv = match_argv(scene)
        at = argv.index("--start") + 1
        argv[at:at + 3] = start
        cases.append((name, argv, "bad", ["--start"]))
    lower = mayacam("lower_jt.txt", "jt_intcalib\n1200\n0\n0\n0.4\n")
    argv = ["import", "--camera", str(lower), "--images1", str(scene["folder"] / "jt"), "--model",
            f"femoral={scene['mesh']}", "--out", str(folder / "lower.fluoro"), "--force"]
    cases.append(("jointtrack_lower_case_header", argv, "warned", [str(lower)]))
    cases += _issue44_cases(scene, folder, good, mayacam)
    if real is not None and (real / "biplane-tka" / "pairs.csv").is_file():
        cases += bounded_cases(real / "biplane-tka")
    return cases


def _issue44_cases(scene: dict, folder: Path, mayacam2: str, mayacam) -> list:
    """Issue 44's bad inputs, each refused naming the input at fault."""
    import cv2
    import tifffile

    from fluorogui.io.calibration import load_view, save_view_mayacam1

    cases = []
    for name, value in (("image_all_0_tiff", 0), ("image_all_255_tiff", 255)):
        tifffile.imwrite(folder / f"{name}.tif", np.full((48, 64), value, np.uint8))
        cases.append((name, match_argv(scene, img0=folder / f"{name}.tif"), "bad", [str(folder / f"{name}.tif")]))
    jpeg = cv2.imencode(".jpg", np.linspace(0, 255, 64 * 48).reshape(48, 64).astype(np.uint8))[1].tobytes()
    (folder / "cut.jpg").write_bytes(jpeg[: len(jpeg) * 2 // 3] + b"\xff\xd9")  # cut, its end marker kept
    cases.append(("jpeg_truncated", match_argv(scene, img1=folder / "cut.jpg"), "bad", [str(folder / "cut.jpg")]))
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    far = folder / "far_outline.csv"
    far.write_text("u,v\n" + "".join(f"{5032 + 15 * np.cos(a):.3f},{24 + 15 * np.sin(a):.3f}\n" for a in t))
    cases.append(("outline_5000_px_off", match_argv(scene, outline0=far), "bad", [str(far)]))
    twice = mayacam("twice.txt", mayacam2 + "\nimage size\n640,480\n")
    arabic = folder / "arabic.txt"  # the image size in Arabic-Indic digits, which float() reads
    arabic.write_text(mayacam2.replace("64,48", "\u0666\u0664,\u0664\u0668", 1), encoding="utf-8")
    save_view_mayacam1(load_view(scene["cam0"]), folder / "mayacam1.txt")
    lines = (folder / "mayacam1.txt").read_text().splitlines()
    lines[1] = "1e308," + lines[1].split(",", 1)[1]
    turned = mayacam("angle_1e308.txt", "\n".join(lines) + "\n")
    for name, path in (("calibration_image_size_twice", twice), ("calibration_arabic_indic_digits", arabic),
                       ("mayacam1_angle_1e308", turned)):
        cases.append((name, match_argv(scene, cam0=path), "bad", [str(path)]))
    triangle = folder / "triangle.stl"
    triangle.write_text("solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 10 0 0\nvertex 0 10 0\n"
                        "endloop\nendfacet\nendsolid t\n")
    cases.append(("mesh_one_triangle_10_mm", match_argv(scene, mesh=triangle), "bad", [str(triangle)]))
    argv = match_argv(scene)
    at = argv.index("--start") + 7
    cases.append(("start_seven_numbers", argv[:at] + ["1"] + argv[at:], "bad", ["--start"]))
    argv = match_argv(scene)
    at = argv.index("--start") + 4
    argv[at:at + 3] = ["1e6", "1e6", "1e6"]
    cases.append(("start_angles_1e6", argv, "bad", ["--start"]))
    blank = folder / "blank.tif"
    tifffile.imwrite(blank, np.zeros((48, 64), np.uint8))
    for name, image in (("pairs_lists_a_blank_image", blank), ("pairs_lists_a_csv", scene["outline0"])):
        pairs = folder / f"{name}.csv"
        pairs.write_text(f"frame,cam1,cam2\n0,{image},{scene['img1']}\n")
        cases.append((name, repeat_argv(scene, pairs=pairs), "bad", [str(pairs), pairs.name]))
    return cases


def bounded_cases(data: Path) -> list[tuple[str, list[str], str, list[str]]]:
    """Matches on the real biplane data that took minutes (issue 44): the paper method on
    automatic outlines, and a femoral start 54 mm off its reference pose (frame 0). Each
    must end within ``BOUNDED_SECONDS``, matched or flagged."""
    import csv

    reference = Path(__file__).resolve().parents[1] / "data" / "biplane_reference_poses.csv"
    with open(reference, newline="") as handle:
        row = next(r for r in csv.DictReader(handle) if r["frame"] == "0" and r["component"] == "femoral")
    pose = [float(row[k]) for k in ("x", "y", "z", "alpha", "beta", "gamma")]
    base = ["match", "--camera", str(data / "calibration" / "cam1_mayacam2.txt"), "--camera",
            str(data / "calibration" / "cam2_mayacam2.txt"), "--image", str(data / "cam1" / "000000.tif"),
            "--image", str(data / "cam2" / "000522.tif"), "--model", str(data / "models" / "femoral_component.stl"),
            "--json"]
    off = [pose[0] + 54.0, *pose[1:]]
    return [("paper_method_automatic_outlines", base + ["--start", *map(str, pose), "--method", "paper"], "bounded",
             []),
            ("start_54_mm_off", base + ["--start", *map(str, off)], "bounded", [])]


def judge(case: tuple[list[str], str, list[str]], result: dict) -> str:
    """One of: ok, crash, hang (no answer, or one after more than ``BOUNDED_SECONDS``),
    internal_error, escaped, bad_accepted, unnamed, many_lines."""
    argv, expect, names = case
    code, stderr = result["code"], result["stderr"]
    if isinstance(code, str):
        return "crash" if code.startswith("crash") else "hang" if code == "hang" else "escaped"
    if "Traceback" in stderr:
        return "escaped"
    if code == 1:
        return "internal_error"
    if result.get("seconds", 0.0) > BOUNDED_SECONDS:
        return "hang"
    if expect == "bounded":
        return "ok" if code in (0, 3) else "bad_refused"
    lines = stderr.strip().splitlines()
    if expect == "warned":
        warned = any(line.startswith("fluorogui: warning: ") and any(n in line for n in names) for line in lines)
        return "ok" if code == 0 and warned else "unwarned" if code == 0 else "internal_error" if code == 1 else \
            "bad_refused"
    if code == 2:
        if len(lines) != 1:
            return "many_lines"
        if any(name in lines[0] for name in names):
            return "ok"
        # a mutated file may still be valid: then a refusal of the combination that names
        # another input file (say, an image listed in pairs.csv where no outline was found
        # with a changed calibration) is a clean, named message
        named = lines[0].removeprefix("fluorogui: error: ").split(": ", 1)[0]
        return "ok" if expect == "any" and Path(named).is_file() else "unnamed"
    if expect == "bad":
        return "bad_accepted"
    return "ok" if code in (0, 3) else "internal_error"

