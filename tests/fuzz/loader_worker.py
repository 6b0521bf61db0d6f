"""Run one loader over many files in this process and report each outcome as a JSON line:
``{"path", "outcome": "accepted" | "refused" | "escaped", "message"}``.

``python loader_worker.py LOADER FILE...``; the parent (``fuzz_loaders`` below, the tests and
``tools/fuzz.py``) runs it as a child so that a crash or a hang of a C library (VTK,
OpenCV, libtiff) is seen as such instead of killing the test run."""
from __future__ import annotations

import json
import os
import random
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def _loaders():
    from fluorogui.io.calibration import load_view
    from fluorogui.io.images import read_image
    from fluorogui.io.importer import read_pairs_csv
    from fluorogui.io.meshes.read import load_mesh
    from fluorogui.io.outlines import read_outline_csv
    from fluorogui.io.pose_files import read_reference_poses
    from fluorogui.io.project.document import load_project

    return {"calibration": load_view, "image": read_image, "mesh": load_mesh, "outline": read_outline_csv,
            "pairs": read_pairs_csv, "reference": read_reference_poses, "project": load_project}


def main(argv: list[str]) -> int:
    from fluorogui.io.errors import InputError

    loader = _loaders()[argv[0]]
    for name in argv[1:]:
        try:
            loaded = loader(name)
            outcome, message = "accepted", ""
            if argv[0] == "project":
                outcome, message = _round_trip(loaded, name)
        except InputError as exc:
            outcome, message = "refused", str(exc)
        except Exception as exc:  # noqa: BLE001 - what the fuzz run counts
            outcome, message = "escaped", f"{type(exc).__name__}: {exc}"[:300]
        print(json.dumps({"path": name, "outcome": outcome, "message": message}), flush=True)
    return 0


def _round_trip(project, name: str) -> tuple[str, str]:
    """An accepted project must save and reopen unchanged: else "unsaveable"."""
    from fluorogui.io.errors import InputError
    from fluorogui.io.project.document import load_project, save_project

    again = Path(name).with_name(Path(name).stem + ".again.fluoro")
    try:
        save_project(project, again)
        if load_project(again) != project:
            return "unsaveable", "reopened differently"
    except InputError as exc:
        return "unsaveable", str(exc)
    finally:
        again.unlink(missing_ok=True)
    return "accepted", ""


# -- the parent's side --------------------------------------------------------------------------
def names_the_file(message: str, path: str) -> bool:
    """One line that starts with the file's path, or with a file it lists and names it."""
    if "\n" in message:
        return False
    return message.startswith(f"{path}: ") or (Path(path).name in message and message.startswith("/"))


def mutate(data: bytes, rng: random.Random) -> bytes:
    """One of: flip bytes, cut the file, insert junk, repeat a slice, or change a number."""
    data = bytearray(data)
    kind = rng.randrange(5)
    if kind == 0 and data:
        for _ in range(rng.randint(1, 8)):
            data[rng.randrange(len(data))] = rng.randrange(256)
    elif kind == 1:
        data = data[: rng.randrange(len(data) + 1)]
    elif kind == 2:
        at = rng.randrange(len(data) + 1)
        data[at:at] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 32)))
    elif kind == 3 and data:
        a = rng.randrange(len(data))
        b = min(len(data), a + rng.randint(1, 200))
        data[b:b] = data[a:b] * rng.randint(1, 20)
    else:
        text = data.decode("latin-1")
        digits = [i for i, c in enumerate(text) if c.isdigit()]
        if digits:
            i = rng.choice(digits)
            text = text[:i] + rng.choice(["999999999999", "-1", "nan", "1e999", "0", "x"]) + text[i + 1:]
        data = bytearray(text.encode("latin-1"))
    return bytes(data)


def fuzz_loaders(seeds: dict[str, list[Path]], folder: Path, per_seed: int, seed: int = 0,
                 timeout: float = 120.0, bad: dict[str, list[Path]] | None = None) -> dict:
    """Mutate every seed file ``per_seed`` times, run each loader's files in a child, count.

    ``seeds`` maps a loader name to valid files of its formats, ``bad`` to files that must
    be refused. Counts: cases, accepted, refused, escaped exceptions, unsaveable projects
    (accepted but not saved and reopened unchanged), crashes (child killed by a signal),
    hangs (timeout), messages not naming the file, known-bad files accepted; ``examples``
    keeps the first few problems."""
    rng = random.Random(seed)
    counts = {"cases": 0, "accepted": 0, "refused": 0, "escaped": 0, "unsaveable": 0, "crashes": 0, "hangs": 0,
              "unnamed": 0, "bad_accepted": 0, "examples": []}
    for loader, files in seeds.items():
        cases = []
        for source in files:
            data = Path(source).read_bytes()
            for k in range(per_seed):
                case = folder / f"{loader}_{Path(source).stem}_{k}{Path(source).suffix}"
                case.write_bytes(mutate(data, rng))
                cases.append(case)
        known_bad = {str(p) for p in (bad or {}).get(loader, [])}
        cases += [Path(p) for p in known_bad]
        counts["cases"] += len(cases)
        pending = list(cases)
        while pending:  # a crash ends a child: go on after the file that crashed it
            env = dict(os.environ, PYTHONPATH=str(REPO))
            child = subprocess.Popen([sys.executable, __file__, loader, *map(str, pending)], stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL, text=True, env=env)
            try:
                out, _ = child.communicate(timeout=timeout)
            except subprocess.TimeoutExpired:
                child.kill()
                out, _ = child.communicate()
                hung = True
            else:
                hung = False
            done = [json.loads(line) for line in out.splitlines() if line.startswith("{")]
            for row in done:
                counts[row["outcome"]] += 1
                if row["outcome"] == "accepted" and row["path"] in known_bad:
                    counts["bad_accepted"] += 1
                    counts["examples"].append(row)
                unnamed = row["outcome"] == "refused" and not names_the_file(row["message"], row["path"])
                counts["unnamed"] += unnamed
                if row["outcome"] in ("escaped", "unsaveable") or unnamed:
                    counts["examples"].append(row)
            pending = pending[len(done):]
            if pending:
                counts["hangs" if hung else "crashes"] += 1
                counts["examples"].append({"path": str(pending[0]), "outcome": "hang" if hung else
                                           f"crash (exit {child.returncode})"})
                pending = pending[1:]
    counts["examples"] = counts["examples"][:10]
    return counts


if __name__ == "__main__":
    sys.path.insert(0, str(REPO))
    sys.exit(main(sys.argv[1:]))
