"""Render the validation results file (``docs/validation/results.json``) into the docs.

The file is written by ``docs/validation/regenerate.py``, which runs ``fluorogui validate``
(and ``fluorogui bench``) and keeps each command's own ``results.json`` unchanged under
``runs[i]["results"]``, with a stamp: the fluorogui version that ran, the date and the
machine. Nothing here measures anything or edits a number: every figure on the page is
computed from that file when the docs are built.

Directives::

    .. validation-stamp::            the version, date, machine and total time
    .. validation-run:: NAME         one run: its command line and its table(s)

The file is set in ``conf.py`` as ``validation_results_file`` (relative to the docs).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

from docutils import nodes
from docutils.parsers.rst import Directive
from docutils.statemachine import StringList
from sphinx.errors import ExtensionError

DOF = ("x", "y", "z", "alpha", "beta", "gamma")
DOF_HEAD = ("x (mm)", "y (mm)", "z (mm)", "α (°)", "β (°)", "γ (°)")


def _load(env) -> dict:
    path = Path(env.srcdir) / env.config.validation_results_file
    env.note_dependency(str(path))
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ExtensionError(f"validation results {path}: {exc}") from exc


def _num(value, digits: int = 3) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "–"
    return f"{value:.{digits}f}"


def _table(head: list[str], rows: list[list[str]], widths: str = "auto") -> list[str]:
    out = [".. list-table::", "   :header-rows: 1", f"   :widths: {widths}", ""]
    for row in [head, *rows]:
        out.append(f"   * - {row[0]}")
        out += [f"     - {cell}" for cell in row[1:]]
    return out + [""]


def _within(errors: list, basin_mm: float, basin_deg: float) -> list[bool]:
    return [max(abs(e) for e in err[:3]) <= basin_mm and max(abs(e) for e in err[3:]) <= basin_deg
            for err in errors]


def _idealized(run: dict) -> list[str]:
    basin_mm, basin_deg = run.get("basin", (0.05, 0.05))
    counts, errors_rows = [], []
    totals = {"runs": 0, "within": 0, "false": 0, "worst_mm": 0.0, "worst_deg": 0.0}
    for case in run["results"]["cases"]:
        errors = case["errors"]
        converged = [r["converged"] for r in case["runs"]]
        within = _within(errors, basin_mm, basin_deg)
        false = sum(c and not w for c, w in zip(converged, within))
        s = case["summary"]
        worst_mm = max(max(abs(e) for e in err[:3]) for err in errors)
        worst_deg = max(max(abs(e) for e in err[3:]) for err in errors)
        totals["runs"] += len(errors)
        totals["within"] += sum(within)
        totals["false"] += false
        totals["worst_mm"] = max(totals["worst_mm"], worst_mm)
        totals["worst_deg"] = max(totals["worst_deg"], worst_deg)
        name = Path(case["model"]).stem.replace("_component", "").replace("_", " ")
        name += f" ({case['variant']})" if case.get("variant") else ""
        if case["method"] != "fast":
            name += f", {case['method']}"
        counts.append([name, case["label"], f"{s['n_converged']}/{s['n_runs']}", f"{sum(within)}/{len(errors)}",
                       str(false), f"{_num(worst_mm)} / {_num(worst_deg)}", _num(s["median_seconds"], 2)])
        errors_rows.append([name, case["label"].split(" [")[0],
                            *[f"{_num(m)} ± {_num(sd)}" for m, sd in zip(s["mean"], s["sd"])]])
    lines = _table(["model", "case", "converged", f"within {basin_mm:g} mm / {basin_deg:g}°", "converged outside",
                    "worst start (mm / °)", "s per match"], counts)
    lines.append(f"All cases: **{totals['within']} of {totals['runs']}** starts ended within "
                 f"{basin_mm:g} mm / {basin_deg:g}° of the truth; **{totals['false']}** converged outside it; "
                 f"the worst start ended {_num(totals['worst_mm'])} mm / {_num(totals['worst_deg'])}° off.")
    lines += ["", "Error of the converged starts, mean ± SD (mm, degrees):", ""]
    lines += _table(["model", "case", *DOF_HEAD], errors_rows)
    return lines


def _spheres(run: dict) -> list[str]:
    lines = []
    for method, out in run["results"]["methods"].items():
        rows = [[pair, _num(m), _num(sd), _num(r)] for pair, m, sd, r in
                zip(out["pairs"], out["pair_mean_mm"], out["pair_sd_mm"], out["pair_rmse_mm"])]
        lines += [f"Method ``{method}``: separation of adjacent spheres (true 12.70 mm).", ""]
        lines += _table(["pair", "mean (mm)", "SD (mm)", "RMSE (mm)"], rows)
        lines += [f"Over all pairs: mean error **{_num(out['mean_error_mm'], 4)} mm**, SD "
                  f"{_num(out['sd_mm'], 4)} mm, RMSE {_num(out['rmse_mm'], 4)} mm; {out['converged']} of "
                  f"{out['runs']} matches converged; median {_num(out['median_seconds'], 2)} s per match.", ""]
    return lines


def _repeatability(run: dict) -> list[str]:
    rows, worst = [], [0.0, 0.0]
    for case in run["results"]["cases"]:
        s = case["summary"]
        resid = case.get("per_view_mean_mm", [])
        worst = [max(worst[0], max(s["sd"][:3])), max(worst[1], max(s["sd"][3:]))]
        rows.append([case["label"], case["method"], f"{s['n_converged']}/{s['n_runs']}",
                     *[_num(v) for v in s["sd"]], " / ".join(_num(r) for r in resid),
                     _num(s["median_seconds"], 2)])
    head = ["frame", "method", "converged", *[f"SD {d}" for d in DOF_HEAD], "residual per view (mm)",
            "s per match"]
    lines = _table(head, rows)
    lines.append(f"Worst SD over the frames: **{_num(worst[0])} mm** and **{_num(worst[1])}°**.")
    return lines + [""]


def _bench(run: dict) -> list[str]:
    rows = [[Path(r["model"]).stem.replace("_", " "), r["method"], _num(r["median_s"]), _num(r["min_s"]),
             _num(r["max_s"]), _num(r["median_ms_per_call"], 1), f"{r['median_calls']:.0f}",
             f"{r['converged']}/{r['runs']}"] for r in run["results"]]
    return _table(["model", "method", "median s", "min s", "max s", "ms per call", "calls", "converged"], rows)


RENDERERS = {"idealized": _idealized, "spheres": _spheres, "repeatability": _repeatability, "bench": _bench}


class _ResultsDirective(Directive):
    has_content = False

    def _render(self, lines: list[str]) -> list[nodes.Node]:
        container = nodes.container(classes=["validation-results"])
        self.state.nested_parse(StringList(lines, source="validation results"), self.content_offset, container)
        return [container]


class ValidationStamp(_ResultsDirective):
    def run(self):
        data = _load(self.state.document.settings.env)
        st = data["stamp"]
        m = st["machine"]
        lines = [
            f"Produced by fluorogui **{st['fluorogui_version']}** on **{st['date']}** in "
            f"{_num(st['seconds'] / 60, 0)} minutes, with ``{st['regenerate']}``.",
            "",
            f"Machine: {m['cpu']}, {m['cores']} cores, {m['memory_gib']:.0f} GiB, {m['platform']}; "
            f"Python {m['python']}, NumPy {m['numpy']}, SciPy {m['scipy']}, OpenCV {m['opencv']}; load average "
            f"{m['load_average']} at the start (the machine is shared, so times vary with the load).",
            "",
        ]
        return self._render(lines)


class ValidationRun(_ResultsDirective):
    required_arguments = 1

    def run(self):
        data = _load(self.state.document.settings.env)
        name = self.arguments[0]
        runs = {r["name"]: r for r in data["runs"]}
        if name not in runs:
            raise self.error(f"no run {name!r} in the validation results (runs: {', '.join(runs)})")
        run = runs[name]
        lines = [".. code-block:: console", "", f"   $ {run['command']}", "",
                 f"*{_num(run['seconds'] / 60, 1)} minutes.*", ""]
        lines += RENDERERS[run["kind"]](run)
        return self._render(lines)


def setup(app):
    app.add_config_value("validation_results_file", "validation/results.json", "env")
    app.add_directive("validation-stamp", ValidationStamp)
    app.add_directive("validation-run", ValidationRun)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
