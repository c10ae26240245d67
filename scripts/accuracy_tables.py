"""The tables of docs/accuracy.md, from a study's ``study.json`` (and, optionally, measured step costs).

    python scripts/accuracy_tables.py STUDY/study.json --probes eta_z1,eta_z2,eta_z3 [--costs costs.jsonl]...

Prints Markdown: the peak error of each run at each of the probes, the
observed orders of the worst of them between successive Δt, and the cost
to reach a 5 % and a 1 % peak error per coupler.  The cost is the
study's own wall time of each run, or, with ``--costs`` (the JSON lines of
``benchmarks/coupled_step.py``: per coupler the median seconds of a step,
all couplers measured side by side in one run), steps × median step:
costs a shared machine cannot skew between couplers.  A target no run
reached is extrapolated from the coupler's finest run with its observed
order (``multilayer.campaign.accuracy.cost_to_target``) and marked so.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from multilayer.campaign.accuracy import cost_cell, cost_to_target, observed_orders

TARGETS = (0.05, 0.01)


def label_of(run: dict) -> str:
    return run["coupler"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("study", type=Path)
    ap.add_argument("--probes", required=True, help="comma list of η probe names")
    ap.add_argument("--costs", type=Path, action="append", default=[],
                    help="JSON lines of benchmarks/coupled_step.py (repeatable: the mean of the runs' medians)")
    args = ap.parse_args(argv)
    data = json.loads(args.study.read_text())
    probes = args.probes.split(",")
    medians: dict[str, list[float]] = {}
    for path in args.costs:
        for line in path.read_text().splitlines():
            row = json.loads(line)
            key = json.loads(row["coupler"]) if row["coupler"].startswith('"') else row["coupler"]
            medians.setdefault(key, []).append(row["median.step"])
    step_cost = {k: {"median.step": sum(v) / len(v)} for k, v in medians.items()}
    runs = [r for r in data["runs"] if r["compared"] and r["status"] == "ok"]
    couplers = list(dict.fromkeys(label_of(r) for r in runs))
    spec = {c["label"]: c["override"] for c in data["couplers"]}

    def worst(run, key="peak_error"):
        return max(run["probes"][p][key] for p in probes)

    def cost(run):
        if not step_cost:
            return run["wall_time_s"], "wall time of the run (s)"
        key = spec[label_of(run)].split("=", 1)[1]
        key = json.loads(key) if key.startswith('"') else key
        row = step_cost.get(key) or step_cost.get(json.dumps(key))
        return run["steps"] * row["median.step"], "steps × median step (s)"

    print("| coupler | Δt (s) | " + " | ".join(f"peak error {p}" for p in probes) + " | L∞ error (max) | cost |")
    print("|---|---|" + "---|" * len(probes) + "---|---|")
    for r in runs:
        cells = " | ".join(f"{100 * r['probes'][p]['peak_error']:.2f} %" for p in probes)
        print(f"| `{label_of(r)}` | {r['dt']:g} | {cells} | {100 * worst(r, 'relative_linf'):.2f} % | "
              f"{cost(r)[0]:.3g} |")
    print()
    print("| coupler | orders of the worst peak error | orders of the worst L∞ error |")
    print("|---|---|---|")
    orders = {}
    for c in couplers:
        mine = sorted((r for r in runs if label_of(r) == c), key=lambda r: -r["dt"])
        p = observed_orders([r["dt"] for r in mine], [worst(r) for r in mine])
        q = observed_orders([r["dt"] for r in mine], [worst(r, "relative_linf") for r in mine])
        orders[c] = (mine, p)
        print(f"| `{c}` | " + ", ".join("—" if x is None else f"{x:.2f}" for x in p) + " | "
              + ", ".join("—" if x is None else f"{x:.2f}" for x in q) + " |")
    print()
    _, unit = cost(runs[0])
    # the baseline: the first coupler labelled kinematic-splitting (the bare name, or with its parameters)
    baseline = next((c for c in orders if c.split("[")[0] == "kinematic-splitting"), None)
    print(f"| coupler | 5 %: {unit} | 1 %: {unit} | 1 %: × {baseline or '—'} |")
    print("|---|---|---|---|")
    table = {}
    for c, (mine, p) in orders.items():
        wall = [cost(r)[0] for r in mine]
        err = [worst(r) for r in mine]
        table[c] = [cost_to_target(wall, err, target, finest=len(mine) - 1, order=p[-1] if p else None)
                    for target in TARGETS]
    base = table.get(baseline)
    for c, got in table.items():
        cells = [cost_cell(g) for g in got]
        ratio = ""
        if base and base[1]["wall_time_s"] and got[1]["wall_time_s"]:
            ratio = f"{base[1]['wall_time_s'] / got[1]['wall_time_s']:.3g}× faster"
        print(f"| `{c}` | {cells[0]} | {cells[1]} | {ratio} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
