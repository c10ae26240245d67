"""The study's report as people read it: ``study.json``, ``study.md``, ``pareto.png``, ``orders.png`` (and
``tolerance.png`` when adaptive runs are in it).

Everything here is drawn from :func:`multilayer.campaign.study.study_data`'s
dictionary alone, so a report can be made again from a ``study.json``.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from multilayer.campaign.report import cell
from multilayer.campaign.study import BASELINE, TARGETS, dt_sequences
from multilayer.results.campaign import claim
from multilayer.results.files import write_atomically
from multilayer.results.reading import without_nan

ERROR_AXIS = "relative L∞ error of η, max over probes (–)"


def _pct(value: float | None) -> str:
    return "—" if value is None else f"{100 * value:.3g} %"


def markdown(data: Mapping[str, Any]) -> str:
    """``study.md``: the command, the reference, then runs, orders, Pareto front and costs."""
    ref, rows = data["reference"], data["runs"]
    lines = [f"# Study: {data['title']}" if data["title"] else "# Study", "", "    " + data["command"], ""]
    if ref["label"] is None:
        lines += ["No reference: no run ended ok, so no error is measured.", ""]
    else:
        how = ("`--reference`, run into `reference/`" if ref["source"] == "--reference"
               else "the finest run of the highest-order coupler")
        lines += [f"Reference: `{ref['label']}` ({how}; status {ref['status']}, Δt = {cell(ref.get('dt'))} s, "
                  f"nz = {cell(ref.get('nz'))}, formal order {cell(ref.get('order'))}).", ""]
        rich = ref["richardson"]
        if rich.get("estimated"):
            parts = [f"{name} ≈ {_pct(rich[key]['estimate'])} (p = {cell(rich[key]['order'])}, "
                     f"{rich[key]['order_from']})" for key, name in (("error", "error"), ("peak_error", "peak error"))]
            scaled = (f", times (Δt_ref/Δt_fine)^p = {cell(rich['error']['scale'])} for the reference's Δt"
                      if rich["error"]["scale"] != 1.0 else "")
            lines += [f"Its own error by Richardson from `{rich['coarse']}` and `{rich['fine']}` (Δt ratio "
                      f"{cell(rich['ratio'])}{scaled}): " + "; ".join(parts) + ". Errors below that are not resolved.",
                      ""]
        else:
            lines += [f"Its own error is not estimated: {rich['note']}.", ""]
    if data["space_error_included"]:
        lines += ["Some runs are on another mesh (nz) than the reference: their error includes the space "
                  "error, not only the time error.", ""]
    lines += ["`error`: max over the η probes of max_t |η − η_ref| / max_t |η_ref|; `peak error`: max over the "
              "η probes of |max_t η − max_t η_ref| / |max_t η_ref|; `arrival`: the largest |time of max η − the "
              "reference's| over the probes.", ""]
    if isinstance(data.get("probes"), list):
        lines += ["The η probes measured (`--probes`): " + ", ".join(f"`{p}`" for p in data["probes"]) + ".", ""]
    lines += ["## Runs", "", "| run | status | Δt (s) | nz | wall time (s) | steps | DOFs | error | peak error "
              "| arrival (s) |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        arrivals = [abs(e["arrival_diff_s"]) for e in r["probes"].values() if e["arrival_diff_s"] is not None]
        error = "(reference)" if r["reference"] else ("not compared" if r["not_compared"] else cell(r["error"]))
        step = f"adaptive, tol {cell(r['tolerance'])}" if r.get("tolerance") else cell(r["dt"])
        lines.append(f"| `{r['label']}` | {r['status']} | {step} | {cell(r['nz'])} | "
                     f"{cell(r['wall_time_s'])} | {cell(r['steps'])} | {cell(r['dofs_total'])} | {error} | "
                     f"{cell(r['peak_error'])} | {cell(max(arrivals) if arrivals else None)} |")
    notes = [f"- `{r['label']}`: {r['reason'] or r['not_compared']}" for r in rows
             if r["status"] != "ok" or r["not_compared"]]
    if notes:
        lines += ["", "Failed or not compared:", "", *notes]
    lines += ["", "## Observed orders", ""]
    if data["orders"]:
        lines += ["p = log(e_coarse/e_fine) / log(Δt_coarse/Δt_fine) between successive Δt of one coupler "
                  "(other keys equal). Against a reference of the same Δt sequence the pair next to it "
                  "over-estimates p (its error is the whole difference to a nearby run).", "",
                  "| coupler | other keys | Δt coarse → fine (s) | order of error | order of peak error |",
                  "|---|---|---|---|---|"]
        for o in data["orders"]:
            others = ", ".join(f"{k}={v}" for k, v in o["group"].items()) or "—"
            lines.append(f"| `{o['coupler']}` | {others} | {cell(o['dt_coarse'])} → {cell(o['dt_fine'])} | "
                         f"{cell(o['error_order'])} | {cell(o['peak_error_order'])} |")
    else:
        lines.append("No order: no two measured runs of one coupler differ only in Δt.")
    if data.get("adaptive"):
        lines += ["", "## Adaptive steps", "", "Runs with `time.tolerance`: the error they reached against the "
                  "tolerance asked (calibrated when the ratio stays near 1), their accepted steps and wall time.", "",
                  "| coupler | other keys | tolerance | error | error / tolerance | peak error | steps | "
                  "wall time (s) |", "|---|---|---|---|---|---|---|---|"]
        for a in data["adaptive"]:
            others = ", ".join(f"{k}={v}" for k, v in a["group"].items()) or "—"
            lines.append(f"| `{a['coupler']}` | {others} | {cell(a['tolerance'])} | {cell(a['error'])} | "
                         f"{cell(a['ratio'])} | {cell(a['peak_error'])} | {cell(a['steps'])} | "
                         f"{cell(a['wall_time_s'])} |")
    lines += ["", "## Pareto front", "", "The runs no other run beats on both wall time and error; slower "
              "runs in this table are more accurate. A run not listed is slower and less accurate than one "
              "that is.", ""]
    by_label = {r["label"]: r for r in rows}
    if data["pareto"]:
        lines += ["| run | wall time (s) | error | peak error |", "|---|---|---|---|"]
        lines += [f"| `{label}` | {cell(by_label[label]['wall_time_s'])} | {cell(by_label[label]['error'])} | "
                  f"{cell(by_label[label]['peak_error'])} |" for label in data["pareto"]]
    else:
        lines.append("No run with a measured error.")
    lines += ["", "## Cost to reach a target peak error", "",
              "The cheapest run within the target (measured); otherwise t_run·(e_run/target)^(1/p) from the "
              "coupler's finest run and the observed order p of its peak error (estimated).", ""]
    costs = data["cost_to_target"]
    baseline = any(c["model"] == BASELINE for c in costs)
    head = ["coupler"]
    for target in TARGETS:
        head += [f"{_pct(target)}: wall time (s)"] + ([f"{_pct(target)}: × {BASELINE}"] if baseline else [])
    lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for coupler in dict.fromkeys(c["coupler"] for c in costs):
        cells = [f"`{coupler}`"]
        for target in TARGETS:
            c = next(e for e in costs if e["coupler"] == coupler and e["target"] == target)
            if c["how"] == "measured":
                cells.append(f"{cell(c['wall_time_s'])} (`{c['run']}`)")
            elif c["how"] == "estimated":
                cells.append(f"{cell(c['wall_time_s'])} (estimated, p = {cell(c['order'])})")
            else:
                cells.append("not reached")
            if baseline:
                cells.append(cell(c["ratio_to_baseline"]))
        lines.append("| " + " | ".join(cells) + " |")
    lines += ["", "![error against wall time](pareto.png)", "", "![error against Δt](orders.png)", ""]
    if data.get("adaptive"):
        lines += ["![error against tolerance](tolerance.png)", ""]
    return "\n".join(lines)


def plot(data: Mapping[str, Any], out: Path) -> None:
    """``pareto.png`` (error against wall time) and ``orders.png`` (error against Δt), log–log."""
    # matplotlib is heavy (and results.figures loads it): imported only when the figures are drawn
    from matplotlib.figure import Figure

    from multilayer.results.figures import save_figure

    rows = data["runs"]
    fig = Figure(figsize=(7, 5), layout="constrained")
    ax = fig.subplots()
    colours = {}
    for by, style, tag in (("dt", "o-", ""), ("tolerance", "s--", " (adaptive)")):  # a line per Δt or tol sweep
        for (coupler, _), group in dt_sequences(rows, by).items():
            group = [r for r in group if r["error"] > 0 and r["wall_time_s"] is not None]
            if group:
                line, = ax.plot([r["wall_time_s"] for r in group], [r["error"] for r in group], style,
                                color=colours.get(coupler + tag), label=None if coupler + tag in colours else coupler + tag)
                colours.setdefault(coupler + tag, line.get_color())
    front = [r for r in rows if r["label"] in data["pareto"] and r["error"] > 0]
    if front:
        ax.plot([r["wall_time_s"] for r in front], [r["error"] for r in front], "o", ms=12, mfc="none",
                color="black", label="Pareto front")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.legend(fontsize="small")
    else:
        ax.text(0.5, 0.5, "no measured error", ha="center", va="center", transform=ax.transAxes)
    ax.set_xlabel("wall time (s)")
    ax.set_ylabel(ERROR_AXIS)
    ax.set_title(f"against {data['reference']['label']}", fontsize="medium")
    ax.grid(alpha=0.3, which="both")
    save_figure(fig, claim(out, "pareto.png"))

    fig = Figure(figsize=(7, 5), layout="constrained")
    ax = fig.subplots()
    groups = dt_sequences(rows)
    anchor = None
    for (coupler, others), group in groups.items():
        group = [r for r in group if r["error"] > 0]
        if not group:
            continue
        name = coupler + "".join(f", {k}={v}" for k, v in others)
        ax.plot([r["dt"] for r in group], [r["error"] for r in group], "o-", label=name)
        anchor = anchor or (group[0]["dt"], group[0]["error"], group[-1]["dt"])
    if anchor is not None:
        dt0, e0, dt1 = anchor
        x = np.array([min(dt1, dt0 / 2), dt0])
        for slope, dashes in ((1, (4, 2)), (2, (1, 2))):
            ax.plot(x, e0 * (x / dt0) ** slope, color="gray", ls="--", dashes=dashes, label=f"slope {slope}")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.legend(fontsize="small")
    else:
        ax.text(0.5, 0.5, "no measured error", ha="center", va="center", transform=ax.transAxes)
    ax.set_xlabel("Δt (s)")
    ax.set_ylabel(ERROR_AXIS)
    ax.grid(alpha=0.3, which="both")
    save_figure(fig, claim(out, "orders.png"))
    if data.get("adaptive"):
        _tolerance_plot(data, out)


def _tolerance_plot(data: Mapping[str, Any], out: Path) -> None:
    """``tolerance.png``: the adaptive runs' error against their tolerance, with error = tol and its × 3 band."""
    from matplotlib.figure import Figure

    from multilayer.results.figures import save_figure

    fig = Figure(figsize=(7, 5), layout="constrained")
    ax = fig.subplots()
    for (coupler, others), group in dt_sequences(data["runs"], "tolerance").items():
        group = [r for r in group if r["error"] > 0]
        if group:
            ax.plot([r["tolerance"] for r in group], [r["error"] for r in group], "s-",
                    label=coupler + "".join(f", {k}={v}" for k, v in others))
    tols = np.array(sorted({a["tolerance"] for a in data["adaptive"]}))
    ax.plot(tols, tols, color="gray", label="error = tolerance")
    ax.fill_between(tols, tols / 3, tols * 3, color="gray", alpha=0.15, label="× 3")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.legend(fontsize="small")
    ax.set_xlabel("time.tolerance (–)")
    ax.set_ylabel(ERROR_AXIS)
    ax.grid(alpha=0.3, which="both")
    save_figure(fig, claim(out, "tolerance.png"))


def write(out: Path, data: Mapping[str, Any]) -> None:
    """``study.json``, ``study.md``, ``pareto.png`` and ``orders.png`` of ``data`` in the folder ``out``."""
    write_atomically(claim(out, "study.json"), json.dumps(without_nan(data), indent=2, allow_nan=False) + "\n")
    write_atomically(claim(out, "study.md"), markdown(data))
    # matplotlib is heavy (results.figures loads it): imported only when the figures are drawn
    from multilayer.results.figures import slide_style

    with slide_style():
        plot(data, out)
