"""The benchmarks page's result tables, regenerated from the experiments' JSON files.

    python benchmarks/tables.py [--results results] [--write PAGE ...]

Reads what the experiments wrote under ``--results`` (``demo/diagnosis.json``,
``paper/results.json``, ``contrast/contrast.json``, ``discovery/discovery_cases.json``,
``silverbox/silverbox.json``, ``cascaded_tanks/cascaded_tanks.json``, ``boucwen/boucwen.json``, ``emps/emps.json``,
and the worst-case benchmark's ``bench_worst_case.json``) and prints one markdown table
per file found, and the leaderboard (:func:`leaderboard`) from the four benchmarks' files. With ``--write PAGE ...`` it replaces, in each page, the text between
``<!-- table:NAME -->`` and ``<!-- /table:NAME -->`` by the table NAME, and leaves the tables whose JSON
is missing as they are. ``make tables`` writes every page of the docs that holds such markers.
"""

from __future__ import annotations

import argparse
import json
import re
from collections.abc import Callable
from pathlib import Path

from torchpaml._render.tables import paper_table
from torchpaml.leaderboard import BENCHMARKS, Benchmark


def _pct(fraction: float | None) -> str:
    return "—" if fraction is None else f"{100 * fraction:.2f}"


def demo(d: dict) -> str:
    lines = ["| model | added | training % | validation % |", "|---|---|---|---|"]
    lines += [f"| {r['model']} | {r['added'] or '—'} | {_pct(r['nrmse_train'])} | {_pct(r['nrmse_validation'])} |"
              for r in d["ladder"]]
    return "\n".join(lines)


def contrast(rows: list[dict]) -> str:
    lines = ["| α | residual | scheme | input | ζ init | ζ̂ | training % | validation % |",
             "|---|---|---|---|---|---|---|---|"]
    lines += [f"| {r['alpha']:g} | {r['residual']} | {r['scheme']} | {r['input']} | {r['zeta_init']:.4f} | "
              f"{r['zeta_hat']:.4f} | {_pct(r['mismatch_train'])} | {_pct(r['mismatch_validation'])} |" for r in rows]
    return "\n".join(lines)


def discovery(cases: dict) -> str:
    lines = ["| case | truth | discovered | recommended | library best | validation % physics / library / neural / "
             "discovered | floor % | s |", "|---|---|---|---|---|---|---|---|"]
    for name, case in cases.items():
        found = case["discovery"]
        v = found["nrmse_validation"]
        shares = " / ".join(_pct(v[k]) for k in ("physics", "library_best", "neural", "discovered"))
        lines.append(f"| {name} | `{case['truth']}` | `{found['expression']}` | {'yes' if found['recommended'] else 'no'} "
                     f"| {found['library_best']} | {shares} | {_pct(case['floor'])} | {case['seconds']:.0f} |")
    return "\n".join(lines)


def silverbox(s: dict) -> str:
    tests = ("test_multisine", "test_arrow_no_extrapolation", "test_arrow_full")
    lines = ["| model | test_multisine | arrow, no extrapolation | arrow, full |", "|---|---|---|---|"]
    lines += [f"| {m['model']} | " + " | ".join(f"{m['rmse'][k]:.2f} mV ({100 * m['nrmse'][k]:.2f} %)" for k in tests)
              + " |" for m in s["models"]]
    found = s.get("discovery")
    discovered = "" if found is None else (
        f" Discovery alone on the linear physics (`--discover`): `{found['expression']}`, test_multisine "
        f"{found['rmse'].get('test_multisine', float('nan')):.2f} mV.")
    return "\n".join(lines) + f"\n\nFound: {', '.join(s['found'])}; {s['seconds']:.0f} s.{discovered}"


def _expression(expression: str | dict[str, str]) -> str:
    """A closed form as written in markdown: one expression, or ``equation: expression`` per equation."""
    if isinstance(expression, str):
        return f"`{expression}`"
    return ", ".join(f"`{equation}`: `{text}`" for equation, text in expression.items())


def tanks(t: dict) -> str:
    lines = ["| model | test RMSE (ours: from the estimation record's state) | test RMSE (official: state from the first "
             "50 samples, scored from sample 50) |", "|---|---|---|"]
    lines += [f"| {m['model']} | {m['rmse']['test']:.3f} V | {_figure(m['rmse'].get('test_official_window'), 'V')} |"
              for m in t["models"]]
    found = t.get("discovery")
    discovered = "" if found is None else (
        f" Discovery alone on the linear TwoTanks (`--discover`): {_expression(found['expression'])}, test RMSE "
        f"{found['rmse']['test']:.3f} V.")
    free = t.get("free_spill")
    spill = "" if free is None else (
        f" The final model refitted with the spill rate free: {free['rate']:.4g} 1/s ({free['solver']}), test RMSE "
        f"{free['rmse']['test']:.3f} V ({free['seconds']:.0f} s).")
    return "\n".join(lines) + f"\n\nFound: {', '.join(t['found'])}; {t['seconds']:.0f} s.{spill}{discovered}"


def boucwen(b: dict) -> str:
    lines = ["| model | test_multisine | test_sinesweep |", "|---|---|---|"]
    lines += [f"| {m['model']} | {m['rmse']['test_multisine']:.2e} m | {m['rmse']['test_sinesweep']:.2e} m |"
              for m in b["models"]]
    return "\n".join(lines) + f"\n\nFound: {', '.join(b['found']) or 'nothing'}; {b['seconds']:.0f} s."


def emps(e: dict) -> str:
    lines = ["| model | test RMSE (position) | test RMSE (velocity) |", "|---|---|---|"]
    lines += [f"| {m['model']} | {m['rmse']['test']:.2f} mm | {m['rmse']['test_velocity']:.1f} mm/s |"
              for m in e["models"]]
    friction = e["friction"]
    return "\n".join(lines) + (f"\n\nFound: {', '.join(e['found']) or 'nothing'}; Coulomb friction "
                               f"{friction['forward_N']:.1f} N against forward motion and {friction['backward_N']:.1f} N "
                               f"against backward; {e['seconds']:.0f} s.")


def _ratio(value: float) -> str:
    return f"{value:.1f}x" if value < 10 else f"{value:.0f}x"


def worst_case(report: dict) -> str:
    """``benchmarks/bench_worst_case.py``'s file: per length and rung, its fit, the slowest refit and its ratio, how many
    refits the gate would run, and the undecided; then the discovery case."""
    lines = ["| samples | rung | rung's fit | slowest refit | its ratio to the fit | the gate refits | undecided |",
             "|---|---|---|---|---|---|---|"]
    for samples, length in report["lengths"].items():
        rungs = dict.fromkeys(c["rung"] for c in length["refits"])
        for rung in rungs:
            rows = [c for c in length["refits"] if c["rung"] == rung]
            slow = max(rows, key=lambda c: c["seconds"])
            undecided = ", ".join(f"{c['effect']} ({c['seconds']:.1f} s)" for c in rows if c["outcome"] == "undecided")
            lines.append(f"| {int(samples):,} | {rung} | {rows[0]['rung_fit']:.2f} s | {slow['effect']} {slow['seconds']:.2f} s "
                         f"| {_ratio(slow['seconds'] / slow['rung_fit'])} | {sum(c['gate_refits'] for c in rows)} of "
                         f"{len(rows)} | {undecided or 'none'} |")
    found = report.get("discovery")
    if found:
        lines += ["", f"Discovery on {found['rung']} ({found['samples']:,} samples): {found['seconds']:.0f} s, "
                      f"{found['screened']} terms screened, `{found['discovery']}`; undecided: "
                      f"{'; '.join(found['undecided']) or 'none'}."]
    bounded = report.get("bounded")
    if bounded:
        lines += ["", *_bounded(bounded)]
    return "\n".join(lines)


STOPPED = "stopped at its budget, the refit's parameters kept"


def _whole(row: dict) -> str:
    """A whole diagnosis of ``bench_worst_case.py --cases``: its seconds, what it added, the discovery."""
    if row["searched"]:
        searched = "searched"
    elif row["added"]:  # the diagnosis then searches on the physics alone, against the ladder's effects
        searched = "found the last rung complete, then searched on the physics alone and kept the ladder's effects"
    else:
        searched = "said the model complete and stopped"
    return (f"{row['seconds']:.1f} s; added {', '.join(row['added']) or 'nothing'}, validation "
            f"{100 * row['nrmse_validation']:.2f} %; the discovery {searched} (`{row['discovery']}`)")


def _bounded(bounded: dict) -> list[str]:
    """The whole runs of ``bench_worst_case.py --cases``, one row each."""
    lines = ["| case | samples | what it took |", "|---|---|---|"]
    memory = bounded.get("memory_rung")
    if memory:
        low, high = memory["bounded"], memory["unbounded"]
        lines.append(f"| the rung after LuGre friction under a sharp sign | {memory['samples']:,} | its refit "
                     f"{low['refit']:.2f} s; the rung's fit {low['rung_fit']:.2f} s "
                     f"({STOPPED if low['stopped'] else 'ended'}, "
                     f"validation {100 * low['nrmse_validation']:.2f} %); unbounded it takes {high['rung_fit']:.2f} s "
                     f"({_ratio(high['rung_fit'] / high['refit'])} its refit; validation "
                     f"{100 * high['nrmse_validation']:.2f} %) |")
    pendulum = bounded.get("pendulum")
    if pendulum:
        lines.append(f"| a pendulum with cubic damping, `diagnose` with the discovery | {pendulum['samples']:,} | "
                     f"{_whole(pendulum)} |")
    chain = bounded.get("two_output")
    if chain:
        lines.append(f"| the two-mass chain (two outputs), `diagnose` with the discovery | {chain['samples']:,} | "
                     f"{_whole(chain['discover'])} |")
        lines.append(f"| the same, the discovery asked to go on (`--discover_always`) | {chain['samples']:,} | "
                     f"{_whole(chain['discover_always'])} |")
    return lines


def _published(benchmark: Benchmark, kind: str) -> str:
    """The published figures of ``kind`` in the benchmark's registry entry, in its order (the best honest one first),
    each with who and where, and its caveat."""
    found = [p for p in benchmark.published if p.kind == kind]
    return "; ".join(f"{p.figure} ({p.model}; {p.source}{f'; {p.caveat}' if p.caveat else ''})" for p in found) \
        or "— (none found)"


def _figure(value: float | None, unit: str) -> str:
    if value is None:
        return "—"
    return f"{value:.2e} {unit}" if value < 1e-3 else f"{value:.3g} {unit}"


def leaderboard(results: Path) -> str | None:
    """One row per benchmark whose JSON is under ``results`` (``make leaderboard``): the linear physics, the final grey
    box, the grey box with the orthogonal residual (and whether its alarm accepts it), and the published best."""
    lines = ["| benchmark (split) | linear physics | final grey box | + orthogonal residual | best published black box "
             "| best published grey box | goal |", "|---|---|---|---|---|---|---|"]
    rows = 0
    for name, benchmark in BENCHMARKS.items():
        path = results / name / f"{name}.json"
        if not path.is_file():
            continue
        data = json.loads(path.read_text())
        split, unit = benchmark.goal_split, benchmark.unit
        hybrid = data["hybrid"]
        verdict = "accepted" if hybrid["accepted"] else \
            "physics complete: not used" if hybrid["reason"].startswith("physics complete") else \
            "alarm: not quoted as accuracy"
        if hybrid["rmse"][split] is None:
            verdict = "the test input leaves the residual's domain; " + verdict
        floor = f" (the noise floor: {data['noise_floor']['rms']:.3g} {unit})" if "noise_floor" in data else ""
        goal = data["goal"]
        met = "met" if goal["met"] else f"not met: {goal['limit']['kind']}"
        lines.append(f"| {name} ({split}) | {_figure(data['models'][0]['rmse'][split], unit)} "
                     f"| {_figure(data['models'][-1]['rmse'][split], unit)} ({data['models'][-1]['model']}) "
                     f"| {_figure(hybrid['rmse'][split], unit)} ({verdict}) | {_published(benchmark, 'black box')} "
                     f"| {_published(benchmark, 'grey box')} | ≤ {_figure(goal['value'], unit)}, {met}{floor} |")
        rows += 1
    return "\n".join(lines) if rows else None


def limits(results: Path) -> str | None:
    """What limits each benchmark's figure (the ``goal`` field of ``make leaderboard``'s files): the goal, the figure
    that counts, whether it meets the goal, and the limit with the numbers that show it."""
    lines = ["| benchmark | goal | figure | limit | what shows it |", "|---|---|---|---|---|"]
    for name in BENCHMARKS:
        path = results / name / f"{name}.json"
        if not path.is_file():
            continue
        data = json.loads(path.read_text())
        goal, unit = data["goal"], data["protocol"]["unit"]
        kind = f"{goal['limit']['kind']}{' (goal met)' if goal['met'] else ''}"
        lines.append(f"| {name} ({goal['split']}) | ≤ {_figure(goal['value'], unit)} "
                     f"| {_figure(goal['figure'], unit)} "
                     f"| {kind} | {goal['limit']['explanation']} |")
    return "\n".join(lines) if len(lines) > 2 else None


def tried(result: dict) -> str:
    """What we tried on the benchmark: every hypothesis the diagnosis fitted (each rung's refitted candidates, then the
    probes of where the final grey box's mismatch points), its validation gain, its test figures, and whether it is
    kept in the final grey box; where the benchmark scores a velocity (``<split>_velocity``), its figures beside."""
    unit, splits = result["protocol"]["unit"], result["protocol"]["test"]
    columns = [(k, k, unit) for k in splits] + [
        (f"{k}_velocity", f"{k} (velocity)", f"{unit}/s") for k in splits
        if any(row["rmse"] and f"{k}_velocity" in row["rmse"] for row in result["tried"])]
    lines = ["| stage | hypothesis | validation gain | " + " | ".join(title for _, title, _ in columns) + " | kept |",
             "|---|---|---|" + "---|" * len(columns) + "---|"]
    for row in result["tried"]:
        gain = "—" if row["validation_gain"] is None else f"{100 * row['validation_gain']:.1f} %"
        figures = ["—" if row["rmse"] is None else _figure(row["rmse"][key], each) for key, _, each in columns]
        stage = row["stage"] if row["place"] is None else f"probe: {row['place']}"
        kept = "yes" if row["kept"] else "no (the place the probes name)" if row["named"] else "no"
        lines.append(f"| {stage} | {row['hypothesis']} | {gain} | " + " | ".join(figures) + f" | {kept} |")
    probed = any(row["stage"] == "probe" for row in result["tried"])
    return "\n".join(lines) + ("" if probed else "\n\nNo probe ran: the final grey box is complete at the noise "
                                                  "level.")


TABLES: dict[str, tuple[str, Callable]] = {
    "demo": ("demo/diagnosis.json", demo),
    "paper": ("paper/results.json", paper_table),
    "contrast": ("contrast/contrast.json", contrast),
    "discovery": ("discovery/discovery_cases.json", discovery),
    "silverbox": ("silverbox/silverbox.json", silverbox),
    "tanks": ("cascaded_tanks/cascaded_tanks.json", tanks),
    "boucwen": ("boucwen/boucwen.json", boucwen),
    "emps": ("emps/emps.json", emps),
    "worst_case": ("bench_worst_case.json", worst_case),
    "silverbox_tried": ("silverbox/silverbox.json", tried),
    "tanks_tried": ("cascaded_tanks/cascaded_tanks.json", tried),
    "emps_tried": ("emps/emps.json", tried),
    "boucwen_tried": ("boucwen/boucwen.json", tried),
}


def tables(results: Path) -> dict[str, str]:
    """NAME -> markdown table, for every result file found under ``results``."""
    found = {}
    for name, (path, render) in TABLES.items():
        if (results / path).is_file():
            found[name] = render(json.loads((results / path).read_text()))
    for name, render in (("leaderboard", leaderboard), ("limits", limits)):
        table = render(results)
        if table is not None:
            found[name] = table
    return found


def write(page: Path, found: dict[str, str]) -> list[str]:
    """Replace each marked table of ``page`` that ``found`` has; returns the names replaced."""
    text, replaced = page.read_text(), []
    for name, table in found.items():
        pattern = re.compile(rf"(<!-- table:{name} -->\n)(?:.*?\n)?(<!-- /table:{name} -->)", re.S)
        if pattern.search(text):
            text = pattern.sub(lambda m, table=table: m.group(1) + table + "\n" + m.group(2), text)
            replaced.append(name)
    page.write_text(text)
    return replaced


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, default=Path("results"), help="the experiments' output folder")
    parser.add_argument("--write", type=Path, nargs="+", default=[], help="pages whose marked tables are replaced")
    args = parser.parse_args()
    found = tables(args.results)
    for page in args.write:
        print(f"replaced in {page}: {', '.join(write(page, found)) or 'nothing'}")
    if not args.write:
        for name, table in found.items():
            print(f"## {name}\n\n{table}\n")


if __name__ == "__main__":
    main()
