"""The comparison report as people read it: a Markdown table and figures."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from multilayer.results.pulse import Speed

NONE = "—"


def cell(value: Any) -> str:
    """A table cell: numbers to 4 significant digits, None as a dash.

    >>> cell(1234.56789), cell(None), cell(3), cell("ok"), cell(4.170193e-15)
    ('1235', '—', '3', 'ok', '4.17e-15')
    """
    if value is None:
        return NONE
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def speed_cell(column: Mapping[str, Any], key: str) -> str:
    """The speed ``key`` of a column: 4 significant digits, or a dash and why there is none."""
    return Speed(column.get(key), column.get(f"{key}_reason") or "not measured").cell()


def pressure_cell(value: float | None, mmhg: float | None) -> str:
    """A pressure as a person reads it: mmHg, then dyn/cm².

    >>> pressure_cell(13332.2, 10.0), pressure_cell(None, None)
    ('10 (1.333e+04 dyn/cm²)', '—')
    """
    return NONE if value is None else f"{mmhg:.4g} ({value:.4g} dyn/cm²)"


def _probe_names(columns: Sequence[Mapping[str, Any]], quantity: str) -> list[tuple[str, Mapping[str, Any]]]:
    """(name, probe entry) of every probe of ``quantity`` in any column, in order of first appearance."""
    seen: dict[str, Mapping[str, Any]] = {}
    for column in columns:
        for name, entry in column["probes"].items():
            if entry["quantity"] == quantity and name not in seen:
                seen[name] = entry
    return list(seen.items())


def _where(entry: Mapping[str, Any]) -> str:
    return f"z = {entry['z']:g}" + (f", line {entry['line']}" if entry.get("line") else "")


def rows(data: Mapping[str, Any]) -> list[tuple[str, list[str]]]:
    """(row title, one cell per variant) of the report table, in order."""
    columns = data["variants"]

    def row(title: str, get) -> tuple[str, list[str]]:
        return title, [cell(get(c)) for c in columns]

    def probe(name: str, key: str):
        return lambda c: c["probes"].get(name, {}).get(key)

    out = [
        row("status", lambda c: c["status"]),
        row("DOFs", lambda c: c["dofs_total"]),
        row("steps", lambda c: c["steps"]),
        row("wall time (s)", lambda c: c["wall_time_s"]),
    ]
    etas = _probe_names(columns, "eta")
    for name, entry in etas:
        title, cells = row(f"max \\|Δη\\| vs `{data['reference']}` at `{name}` ({_where(entry)}) (cm)",
                           probe(name, "max_abs_diff"))
        out.append((title, ["(reference)" if i == 0 else c for i, c in enumerate(cells)]))
    for name, entry in etas:
        out.append(row(f"peak \\|η\\| at `{name}` (cm)", probe(name, "peak")))
        for key, what in (("peak_time", "peak time"), ("half_peak_time", "half-peak time")):
            title, cells = row(f"{what} at `{name}` (s)", probe(name, key))
            unfinished = [c["probes"].get(name, {}).get("peaked") is False and c["probes"][name][key] is not None
                          for c in columns]
            out.append((title, [f"{v} (last row)" if u else v for v, u in zip(cells, unfinished)]))
    for name, entry in [(n, e) for n, e in etas if not e.get("line")] + _probe_names(columns, "p"):
        out.append((f"foot time at `{name}` (s)", [_foot(c["probes"].get(name)) for c in columns]))
    places = {(loop["z"], loop["pressure"], loop["eta"]) for c in columns for loop in c.get("pwv_loop", [])}
    out += [
        ("PWV foot to foot, η probes on the lumen (cm/s)", [speed_cell(c, "pwv_foot_eta") for c in columns]),
        ("PWV foot to foot, p probes (cm/s)", [speed_cell(c, "pwv_foot_p") for c in columns]),
    ]
    for z, pressure, eta in sorted(places):
        out.append((f"PWV from the ΔP–ΔA loop at z = {z:g} (`{pressure}`, `{eta}`) (cm/s)",
                    [_loop(c, z, pressure, eta) for c in columns]))
    out += [
        ("wave speed from peak times (cm/s)", [speed_cell(c, "wave_speed_peak") for c in columns]),
        ("wave speed from half-peak times (cm/s)", [speed_cell(c, "wave_speed_half_peak") for c in columns]),
        ("long-wave speed of the stack √(A/(ρ_f·dA/dP)) (cm/s)", [speed_cell(c, "long_wave_speed") for c in columns]),
        ("peak pressure, mmHg (dyn/cm²)", [pressure_cell(c["peak_pressure"], c.get("peak_pressure_mmHg"))
                                          for c in columns]),
        ("final total energy", [_energy(c) for c in columns]),
        row("ledger max relative residual", lambda c: c["max_relative_residual"]),
    ]
    return out


def _foot(entry: Mapping[str, Any] | None) -> str:
    if not entry or "foot_time" not in entry:
        return NONE
    return cell(entry["foot_time"]) if entry["foot_time"] is not None else f"{NONE} ({entry['foot_reason']})"


def _loop(column: Mapping[str, Any], z: float, pressure: str, eta: str) -> str:
    loop = next((o for o in column.get("pwv_loop", []) if (o["z"], o["pressure"], o["eta"]) == (z, pressure, eta)),
                None)
    return NONE if loop is None else Speed(loop["value"], loop["reason"]).cell()


def _energy(column: Mapping[str, Any]) -> str:
    value = column["final_energy"]
    return NONE if value is None else f"{value:.4g} {column.get('energy_unit') or 'erg/cm'}"


def markdown(data: Mapping[str, Any]) -> str:
    """The whole ``report.md``: title, variants, table, failures, figures."""
    columns = data["variants"]
    lines = [f"# Comparison: {data['title']}" if data["title"] else "# Comparison", ""]
    if data.get("vary"):
        lines += [f"Varied: `--vary {data['vary']}`", ""]
    common = [o for o in columns[0].get("overrides", []) if all(o in c.get("overrides", []) for c in columns)]
    if common:
        lines += ["Every variant: " + " ".join(f"`--set {o}`" for o in common), ""]
    lines += ["Variants (results folder: case file, own overrides):", ""]
    for c in columns:
        sets = " ".join(f"`--set {o}`" for o in c.get("overrides", []) if o not in common)
        lines.append(f"- `{c['out']}/`: `{c.get('case_file', '')}` {sets}".rstrip())
    lines += ["", "| | " + " | ".join(f"`{c['label']}`" for c in columns) + " |",
              "|---|" + "---|" * len(columns)]
    lines += [f"| {title} | " + " | ".join(cells) + " |" for title, cells in rows(data)]
    failed = [c for c in columns if c["status"] != "ok"]
    if failed:
        lines += ["", "Failures:", ""] + [f"- `{c['label']}`: {c['reason'] or 'no reason given'}" for c in failed]
    if any(e.get("peaked") is False and e.get("peak") is not None for c in columns for e in c["probes"].values()):
        lines += ["", ("(last row): the peak is on the last row, so the pulse may not have passed the probe yet; "
                       "the wave speeds leave such probes out.")]
    lines += ["", "![probe time series](probes.png)", "", "![η(z, t) on the lumen line](eta_spacetime.png)", ""]
    return "\n".join(lines)


def plot_compared_probes(runs: Sequence[Any], path: Path) -> Any:
    """One panel per probe (every probe of any run), all runs overlaid against t, each in the unit a person
    reads (:func:`multilayer.results.figures.display`); returns the figure.

    (:func:`multilayer.results.figures.plot_probes` draws the probes of one run.)
    """
    # matplotlib is heavy (and results.figures loads it): imported only when the figure is drawn
    from matplotlib.figure import Figure

    from multilayer.results.figures import fit, label_axis, save_figure, slide_style

    probes: dict[str, Mapping[str, Any]] = {}
    units: dict[str, str] = {}
    for run in runs:
        units = units or dict((run.summary or {}).get("units") or {})
        for p in run.probes:
            probes.setdefault(p["name"], p)
    with slide_style():
        fig = Figure(figsize=(9, 1.4 + 2.6 * max(1, len(probes))), layout="constrained")
        axes = fig.subplots(max(1, len(probes)), 1, sharex=True, squeeze=False)[:, 0]
        if not probes:
            axes[0].text(0.5, 0.5, "no probes", ha="center", va="center", transform=axes[0].transAxes)
            axes[0].set_ylabel("no probes (–)")
        for ax, (name, p) in zip(axes, probes.items()):
            factor = label_axis(ax, p["quantity"], units)
            for run in runs:
                if name in run.series:
                    ax.plot(run.t, factor * run.series[name], label=run.label)
            where = (f"z = {p['z']:g} cm" + (f", r = {p['r']:g} cm" if p.get("r") is not None else "")
                     + (f", line {p['line']}" if p.get("line") else ""))
            ax.set_title(fit(f"{name}: {p['quantity']} at {where}", 7.0))
            ax.grid(alpha=0.3)
        axes[0].legend()
        axes[-1].set_xlabel("t (s)")
        save_figure(fig, path)
    return fig
