"""The stability map as people read it: ``stability.json``, ``stability.md`` and ``stability.png``.

Everything here is drawn from :func:`multilayer.campaign.stability.map_data`'s
dictionary alone: one table (and one panel of the map) per combination of
the ``--vary`` values, couplers × ratios, each cell a verdict.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from multilayer.campaign.stability import VERDICTS
from multilayer.results.campaign import claim
from multilayer.results.files import write_atomically
from multilayer.results.reading import without_nan


def panels(data: Mapping[str, Any]) -> list[tuple[str, dict[tuple[str, float], dict[str, Any]]]]:
    """One panel per combination of the ``--vary`` values: (title, run by (coupler, ratio))."""
    groups: dict[tuple, dict[tuple[str, float], dict[str, Any]]] = {}
    for row in data["runs"]:
        groups.setdefault(tuple(row["values"].items()), {})[row["coupler"], row["ratio"]] = row
    out = []
    for values, cells in groups.items():
        dts = {r["dt"] for r in cells.values() if r["dt"] is not None}  # None: a run without summary.json
        parts = [f"Δt = {_num(dts.pop())} s"] if len(dts) == 1 else []
        parts += [f"{k} = {v}" for k, v in values if k != "time.dt"]
        out.append((", ".join(parts) or "all runs", cells))
    return out


def _num(value: float | None, digits: int = 3) -> str:
    return "—" if value is None else f"{value:.{digits}g}"


def _ratio_order(data: Mapping[str, Any]) -> list[float]:
    """The ratios, heaviest wall first: the map gets harder to the right."""
    return sorted((r["ratio"] for r in data["ratios"]), reverse=True)


def _iterations(row: Mapping[str, Any]) -> str:
    it = row["iterations"]
    if it["mean"] is None:
        return "— it/step"
    return f"{it['mean']:.1f} it/step" + (f" (max {it['max']})" if it["reported"] else "")


def status_cell(row: Mapping[str, Any]) -> str:
    """A cell of the map's table: ``stable, 1.0 it/step, 3.2 s``, ``energy grew (…)``, ``failed after t = … s``.

    A failed run's time is that of its last row (:func:`multilayer.campaign.stability.failure_time`):
    the run got that far, then failed.
    """
    if row["verdict"] == "failed":
        t = row["failure_time_s"]
        return "failed in the first step" if t is None else f"failed after t = {_num(t)} s"
    head = "stable" if row["stable"] else f"energy grew ({row['energy_growth']:.2e})"
    return f"{head}, {_iterations(row)}, {_num(row['wall_time_s'], 2)} s"


def growth_cell(row: Mapping[str, Any]) -> str:
    """A cell of the energy-growth table (the rows written, for a failed run)."""
    growth = row["energy_growth"]
    text = "—" if growth is None else ("∞" if math.isinf(growth) else f"{growth:.2e}")
    return text + (" (failed)" if row["verdict"] == "failed" else "")


def markdown(data: Mapping[str, Any]) -> str:
    """``stability.md``: the command, the ratios and densities, then per panel the map and the energy growth."""
    layer = data["layer"]
    ratios = _ratio_order(data)
    couplers = [c["label"] for c in data["couplers"]]
    lines = [f"# Stability map: {data['title']}" if data["title"] else "# Stability map", "",
             "    " + data["command"], "",
             f"The ratio ρ₁h/(ρ_f R) is set through `{layer['path']}.density` ({layer['model']}, h = "
             f"{_num(layer['thickness'], 6)} cm), ρ_f = {_num(data['fluid_density'], 6)} g/cm³, R = "
             f"{_num(data['radius'], 6)} cm: ρ₁ = ratio · ρ_f · R / h.", "",
             "| ratio ρ₁h/(ρ_f R) | ρ₁ (g/cm³) |", "|---|---|"]
    lines += [f"| {r['text']} | {r['density']:.6g} |" for r in data["ratios"]]
    lines += ["", f"**stable**: the run ended ok and at no step held more energy than it started with plus the "
              f"work put in, to round-off: energy growth = maxₙ (Eₙ − E₀ − Wₙ) / (|E₀| + maxₙ |Wₙ|) ≤ "
              f"{_num(data['tolerance'])}. **energy grew**: ended ok above that. **failed**: the run stopped "
              "after its last row, whose time is given (the reason below names where and when). Iterations: "
              "sub-iterations per step (mean, max) from the `iterations` column; a coupler that writes none "
              "solves once per step (1 it/step). Wall time: of each run, as its `summary.json` has it.", ""]
    for title, cells in panels(data):
        head = "| coupler | " + " | ".join(f"ratio {_num(r, 6)}" for r in ratios) + " |"
        rule = "|---|" + "---|" * len(ratios)
        lines += [f"## {title}", "", head, rule]
        lines += ["| `" + c + "` | " + " | ".join(status_cell(cells[c, r]) if (c, r) in cells else "—"
                                                    for r in ratios) + " |" for c in couplers]
        lines += ["", "Energy growth maxₙ (Eₙ − E₀ − Wₙ) / (|E₀| + maxₙ |Wₙ|):", "", head, rule]
        lines += ["| `" + c + "` | " + " | ".join(growth_cell(cells[c, r]) if (c, r) in cells else "—"
                                                    for r in ratios) + " |" for c in couplers]
        lines.append("")
    unstable = [r for r in data["runs"] if not r["stable"]]
    lines += ["## Runs that are not stable", ""]
    if unstable:
        for r in unstable:
            what = r["reason"] or f"energy growth {growth_cell(r)}"
            lines.append(f"- `{r['label']}` ({r['verdict']}, {_num(r['steps'])} of {_num(r['steps_planned'])} "
                         f"steps): {what}")
    else:
        lines.append("None: every run is stable.")
    silent = sorted({r["coupler"] for r in data["runs"] if not r["iterations"]["reported"]}, key=couplers.index)
    if silent:
        lines += ["", "No `iterations` column (one solve per step, counted as 1 it/step): "
                  + ", ".join(f"`{c}`" for c in silent) + "."]
    lines += ["", "![stability map](stability.png)", ""]
    return "\n".join(lines)


def _annotation(row: Mapping[str, Any]) -> str:
    if row["verdict"] == "failed":
        t = row["failure_time_s"]
        return "failed\nin step 1" if t is None else f"failed after\nt = {_num(t)} s"
    it = row["iterations"]
    text = "— it/step" if it["mean"] is None else f"{it['mean']:.1f} it/step"
    text += f"\nmax {it['max']}" if it["reported"] and it["max"] is not None else ""
    return text + ("" if row["stable"] else f"\ngrowth {row['energy_growth']:.1e}")


def plot(data: Mapping[str, Any], path: Path) -> None:
    """``stability.png``: a panel per :func:`panels` entry, couplers × ratios, coloured by verdict."""
    # matplotlib is heavy (and results.figures loads it): imported only when the map is drawn
    from matplotlib.colors import to_rgb
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    from multilayer.results.figures import save_figure

    ratios = _ratio_order(data)
    couplers = [c["label"] for c in data["couplers"]]
    groups = panels(data)
    label_width = 0.08 * max(len(c) for c in couplers)  # inches of the coupler names
    fig = Figure(figsize=(1.0 + label_width + max(3.5, 1.5 * len(ratios)) * len(groups), 2.0 + 0.8 * len(couplers)),
                 layout="constrained")
    axes = fig.subplots(1, len(groups), sharey=True, squeeze=False)[0]
    blank = to_rgb("#e0e0e0")
    for ax, (title, cells) in zip(axes, groups):
        image = np.array([[to_rgb(VERDICTS[cells[c, r]["verdict"]]) if (c, r) in cells else blank for r in ratios]
                          for c in couplers])
        ax.imshow(image, aspect="auto", interpolation="nearest")
        for i, c in enumerate(couplers):
            for j, r in enumerate(ratios):
                if (c, r) in cells:
                    ax.text(j, i, _annotation(cells[c, r]), ha="center", va="center", fontsize="small")
        ax.set_xticks(range(len(ratios)), [f"{r:g}" for r in ratios])
        ax.set_yticks(range(len(couplers)), couplers)
        ax.set_xticks(np.arange(len(ratios) + 1) - 0.5, minor=True)
        ax.set_yticks(np.arange(len(couplers) + 1) - 0.5, minor=True)
        ax.grid(which="minor", color="white", linewidth=2)
        ax.tick_params(which="minor", length=0)
        ax.set_title(title, fontsize="small")
    axes[0].set_ylabel("coupler")
    fig.supxlabel("wall-to-fluid mass ratio ρ₁h/(ρ_f R) (dimensionless; lighter wall to the right)",
                  fontsize="medium")
    fig.legend(handles=[Patch(color=colour, label=name) for name, colour in VERDICTS.items()],
               loc="outside upper center", ncols=len(VERDICTS), fontsize="small")
    save_figure(fig, path)


def write(out: Path, data: Mapping[str, Any]) -> None:
    """``stability.json``, ``stability.md`` and ``stability.png`` of ``data`` in the folder ``out``."""
    write_atomically(claim(out, "stability.json"), json.dumps(without_nan(data), indent=2, allow_nan=False) + "\n")
    write_atomically(claim(out, "stability.md"), markdown(data))
    # matplotlib is heavy (results.figures loads it): imported only when the figures are drawn
    from multilayer.results.figures import slide_style

    with slide_style():
        plot(data, claim(out, "stability.png"))
