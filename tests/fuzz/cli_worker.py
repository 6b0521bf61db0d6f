"""Run many command lines through ``fluorogui.cli.main`` in one process and report each as
a JSON line ``{"index", "code", "stderr", "seconds"}`` (what the terminal would show on
stderr, and how long the command took).

``python cli_worker.py CASES.json FIRST``: CASES.json holds a list of argv lists; cases from
index FIRST on are run. ``run_cli_cases`` is the parent: it restarts the worker after a
crash or a hang (no line for ``timeout`` seconds) and goes on with the next case."""
from __future__ import annotations

import io
import json
import os
import resource
import select
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def main(cases_file: str, first: int) -> int:
    from fluorogui import cli

    cases = json.loads(Path(cases_file).read_text())
    real_stderr = sys.stderr
    for index in range(first, len(cases)):
        sys.stderr = captured = io.StringIO()
        sys.stdout = io.StringIO()
        started = time.monotonic()
        try:
            code = cli.main(cases[index])
        except SystemExit as exc:  # --help / --version
            code = exc.code if isinstance(exc.code, int) else 0
        except BaseException as exc:  # noqa: BLE001 - counted as escaped by the parent
            code = f"escaped {type(exc).__name__}"
        finally:
            sys.stderr, sys.stdout = real_stderr, sys.__stdout__
        print(json.dumps({"index": index, "code": code, "stderr": captured.getvalue(),
                          "seconds": round(time.monotonic() - started, 2)}), flush=True)
    return 0


def run_cli_cases(cases: list[list[str]], folder: Path, timeout: float = 60.0) -> tuple[list[dict], dict]:
    """Results per case (``code`` is "crash", "hang", an exit code or "escaped ...") and the
    worker processes' peak resident memory (MB)."""
    cases_file = folder / "cli_cases.json"
    cases_file.write_text(json.dumps(cases))
    results: list[dict] = []
    env = dict(os.environ, PYTHONPATH=str(REPO), FLUOROGUI_DATA_DIR=str(folder / "appdata"))
    while len(results) < len(cases):
        child = subprocess.Popen([sys.executable, __file__, str(cases_file), str(len(results))],
                                 stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=env, bufsize=1)
        deadline = time.monotonic() + timeout
        while True:
            ready, _, _ = select.select([child.stdout], [], [], max(0.0, deadline - time.monotonic()))
            if not ready:  # no answer in time: a hang
                child.kill()
                child.wait()
                results.append({"index": len(results), "code": "hang", "stderr": ""})
                break
            line = child.stdout.readline()
            if not line:  # the worker died (or finished)
                child.wait()
                if len(results) < len(cases):
                    results.append({"index": len(results), "code": f"crash {child.returncode}", "stderr": ""})
                break
            if line.startswith("{"):
                results.append(json.loads(line))
                deadline = time.monotonic() + timeout
        child.stdout.close()
    peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
    return results, {"peak_mb": peak_mb}


if __name__ == "__main__":
    sys.path.insert(0, str(REPO))
    sys.exit(main(sys.argv[1], int(sys.argv[2])))
