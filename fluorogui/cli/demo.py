"""``fluorogui demo``: write the built-in demo session (true poses included) to work on."""
from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

from fluorogui.cli.common import UsageError, int_in


def add_parser(sub):
    d = sub.add_parser("demo", help="write the built-in demo session (true poses included)")
    d.add_argument("out", metavar="OUT.fluoro", help="project file to write; its data goes to OUT_data/ beside it")
    d.add_argument("--frames", type=int_in(1, 1000), default=4, help="frames of the knee bend (default 4)")
    d.add_argument("--force", action="store_true", help="replace an existing OUT.fluoro and OUT_data/")
    return d


def run(args) -> int:
    from fluorogui.io.errors import InputError
    from fluorogui.io.project.document import load_project, save_project
    from fluorogui.simulation.demo import build_demo_project

    out = Path(args.out).absolute()
    if out.suffix.lower() != ".fluoro":
        raise UsageError(f"fluorogui: demo: {args.out}: the project file name must end in .fluoro")
    data = out.with_name(out.stem + "_data")
    if (out.exists() or data.exists()) and not args.force:
        raise InputError(out if out.exists() else data, "already exists; use --force to replace it")
    if args.frames < 1:
        raise UsageError("fluorogui: demo: --frames must be at least 1")
    out.parent.mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp(prefix=".demo-", dir=out.parent))
    try:
        built = build_demo_project(scratch, frames=args.frames)
        if data.exists():
            shutil.rmtree(data)
        scratch.rename(data)
        project = load_project(data / built.name)
        (data / built.name).unlink()
        save_project(project, out)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    print(f"wrote {out} ({len(project.frames)} frames; data in {data})")
    return 0
