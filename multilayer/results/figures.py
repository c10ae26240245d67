"""The figures of one run, from its results folder alone: ``multilayer plot DIR`` and the end of ``run``.

* ``eta_spacetime.png`` — η(z, t) on the lumen line (from ``eta_lumen.csv``);
* ``probes.png`` — every probe against time, one panel per quantity, each axis with its unit;
* ``energy.png`` — the energy ledger: stored energy, cumulative work and
  dissipation, and the relative residual of every step;
* ``wss.png`` — the wall shear stress τ_w(z, t) (from ``wss_lumen.csv``) and, under a periodic load, TAWSS and
  OSI along the lumen over the last complete cycle (``summary.json`` ``wss``);
* ``cycles.png`` — under a periodic load, every pressure over each complete cycle, overlaid (mmHg), and the
  largest relative change of the cycle summaries from one cycle to the next (``summary.json`` ``cycles``).

A figure replaces only a file the run owns (its folder's manifest lists it,
:func:`multilayer.results.folder.may_write`); a file of that name the run did
not write is kept, and the figure not drawn.  Every PNG is written to a
fresh temporary and renamed into place: a symbolic link is never followed.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from multilayer.results.cycles import MMHG, inside
from multilayer.results.files import atomic_file
from multilayer.results.folder import may_write
from multilayer.results.reading import lumen_eta, lumen_wss, read_run

#: what each probe quantity is, and its unit (CGS)
QUANTITIES = {
    "eta": ("η, radial wall displacement", "cm"),
    "v": ("v, radial wall velocity", "cm/s"),
    "d_z": ("d_z, axial wall displacement", "cm"),
    "d_r": ("d_r, radial wall displacement", "cm"),
    "u_z": ("u_z, axial fluid velocity", "cm/s"),
    "u_r": ("u_r, radial fluid velocity", "cm/s"),
    "p": ("p, pressure", "dyn/cm²"),
    "flow_rate": ("Q, flow rate", "cm²/s"),
}


def plot_run(folder: Path | str) -> list[Path]:
    """Write the run's figures into ``folder``; returns their paths (those that could be made).

    A figure whose file is in the folder but not the run's (:func:`~multilayer.results.folder.may_write`)
    is not drawn: that file is kept.
    """
    folder = Path(folder)
    run = read_run(folder.name, folder)
    written = []
    radius = (run.case.get("geometry") or {}).get("radius")
    field = lumen_eta(folder, radius) if radius is not None and may_write(folder, "eta_spacetime.png") else None
    if field is not None:
        plot_spacetime({run.case.get("title", folder.name)[:60] or folder.name: field}, folder / "eta_spacetime.png")
        written.append(folder / "eta_spacetime.png")
    if run.probes and len(run.t) and may_write(folder, "probes.png"):
        plot_probes(run, folder / "probes.png")
        written.append(folder / "probes.png")
    if "energy.total" in run.series and len(run.t) and may_write(folder, "energy.png"):
        plot_energy(run, folder / "energy.png")
        written.append(folder / "energy.png")
    wss = lumen_wss(folder) if may_write(folder, "wss.png") else None
    if wss is not None:
        plot_wss(wss, run.summary.get("wss"), folder / "wss.png")
        written.append(folder / "wss.png")
    block = run.summary.get("cycles")
    if isinstance(block, Mapping) and block.get("cycles") and len(run.t) and may_write(folder, "cycles.png"):
        plot_cycles(run, block, folder / "cycles.png")
        written.append(folder / "cycles.png")
    return written


def _where(p) -> str:
    return f"z = {p['z']:g} cm" + (f", r = {p['r']:g} cm" if p.get("r") is not None else "")


def plot_probes(run, path: Path) -> None:
    """One panel per probe quantity, every probe of that quantity against t, the axis in its unit."""
    groups: dict[str, list] = {}
    for p in run.probes:
        groups.setdefault(p["quantity"], []).append(p)
    fig = Figure(figsize=(8, 1.2 + 2.4 * len(groups)), layout="constrained")
    axes = fig.subplots(len(groups), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (quantity, probes) in zip(axes, groups.items()):
        for p in probes:
            ax.plot(run.t, run.series[p["name"]], label=f"{p['name']} ({_where(p)})")
        what, unit = QUANTITIES.get(quantity, (quantity, ""))
        unit = _units(run).get(quantity, unit)
        ax.set_ylabel(f"{what.split(',')[0]} ({unit})" if unit else what)
        ax.set_title(what, fontsize="medium")
        ax.grid(alpha=0.3)
        ax.legend(fontsize="small", ncols=2 if len(probes) > 4 else 1)
    axes[-1].set_xlabel("t (s)")
    save_figure(fig, path)


def _units(run) -> dict[str, str]:
    """The units of the run's integrals as its geometry gave them (``summary.json`` ``units``; per unit depth
    for a run written before they were recorded)."""
    return (getattr(run, "summary", None) or {}).get("units") or {}


def plot_energy(run, path: Path) -> None:
    """Stored energy, cumulative work and dissipation (erg per unit depth, or in the geometry's units), and
    each step's residual."""
    s, t = run.series, run.t
    work = np.cumsum(sum((s[k] for k in s if k.startswith("work.")), np.zeros_like(t)))
    dissipation = np.cumsum(sum((s[k] for k in s if k.startswith("dissipation.")), np.zeros_like(t)))
    stored = s["energy.total"]
    initial = stored[0] - (work[0] - dissipation[0])  # E⁰ = E¹ − work¹ + dissipation¹ (the ledger of step 1)
    fig = Figure(figsize=(8, 6), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True)
    top.plot(t, stored, label="stored energy E")
    top.plot(t, initial + work, label="E⁰ + cumulative work")
    top.plot(t, dissipation, label="cumulative dissipation (viscous, numerical, …)")
    top.set_ylabel(f"energy ({_units(run).get('energy', 'erg/cm')})")
    top.set_title("energy ledger: E = E⁰ + work − dissipation every step", fontsize="medium")
    top.grid(alpha=0.3)
    top.legend(fontsize="small")
    residual = np.maximum(s.get("energy.relative_residual", np.zeros_like(t)), 1e-300)
    bottom.semilogy(t, residual, ".", ms=3)
    bottom.set_ylabel("|residual| / scale")
    bottom.set_xlabel("t (s)")
    bottom.set_title("relative residual of each step's energy identity", fontsize="medium")
    bottom.grid(alpha=0.3)
    save_figure(fig, path)


def _edges(x: np.ndarray) -> tuple[float, float]:
    """The outer edges of pixels centred on the uniformly spaced samples ``x``.

    >>> _edges(np.array([0.0, 1.0, 2.0])), _edges(np.array([3.0]))
    ((-0.5, 2.5), (2.5, 3.5))
    """
    half = 0.5 * (x[-1] - x[0]) / (len(x) - 1) if len(x) > 1 else 0.5
    return float(x[0] - half), float(x[-1] + half)


def save_figure(fig: Figure, path: Path) -> None:
    """Draw ``fig`` on an Agg canvas and write it to ``path`` (100 dpi; a new file renamed over ``path``)."""
    FigureCanvasAgg(fig)
    with atomic_file(path) as f:
        fig.savefig(f, dpi=100, format=Path(path).suffix.lstrip(".").lower() or "png")


def plot_spacetime(fields: Mapping[str, tuple[np.ndarray, np.ndarray, np.ndarray] | None], path: Path) -> None:
    """η(z, t) per run side by side, on one symmetric colour scale."""
    labels = list(fields) or ["(none)"]
    peak = max((float(np.nanmax(np.abs(f[2]))) for f in fields.values() if f is not None), default=0.0) or 1.0
    fig = Figure(figsize=(1.0 + 3.2 * len(labels), 4.5), layout="constrained")
    axes = fig.subplots(1, len(labels), sharey=True, squeeze=False)[0]
    image = None
    for ax, label in zip(axes, labels):
        field = fields.get(label)
        ax.set_title(label, fontsize="medium")
        ax.set_xlabel("z (cm)")
        if field is None:
            ax.text(0.5, 0.5, "no snapshots", ha="center", va="center", transform=ax.transAxes)
            continue
        z, t, eta = field
        image = ax.imshow(eta, origin="lower", aspect="auto", cmap="RdBu_r", vmin=-peak, vmax=peak,
                          extent=(*_edges(z), *_edges(t)), interpolation="nearest")
    axes[0].set_ylabel("t (s)")
    if image is not None:
        fig.colorbar(image, ax=list(axes), label="η (cm)")
    save_figure(fig, path)


def plot_wss(field: tuple[np.ndarray, np.ndarray, np.ndarray], block: Mapping | None, path: Path) -> None:
    """τ_w(z, t) on a symmetric colour scale; below it, with cycles in ``block`` (``summary.json`` ``wss``), TAWSS
    and OSI along the lumen over the last complete cycle."""
    z, t, wss = field
    last = (block or {}).get("cycles") or []
    fig = Figure(figsize=(8, 8 if last else 4.5), layout="constrained")
    axes = fig.subplots(2 if last else 1, 1, squeeze=False)[:, 0]
    peak = float(np.nanmax(np.abs(wss))) or 1.0
    image = axes[0].imshow(wss, origin="lower", aspect="auto", cmap="RdBu_r", vmin=-peak, vmax=peak,
                           extent=(*_edges(z), *_edges(t)), interpolation="nearest")
    axes[0].set_xlabel("z (cm)")
    axes[0].set_ylabel("t (s)")
    axes[0].set_title("wall shear stress τ_w (positive downstream)", fontsize="medium")
    fig.colorbar(image, ax=axes[0], label="τ_w (dyn/cm²)")
    if last:
        cycle = last[-1]
        ax = axes[1]
        ax.plot(block["z"], [np.nan if v is None else v for v in cycle["tawss"]], "C0.-", label="TAWSS")
        ax.set_xlabel("z (cm)")
        ax.set_ylabel("TAWSS (dyn/cm²)", color="C0")
        ax.set_title(f"over the cycle {cycle['start']:g} – {cycle['end']:g} s", fontsize="medium")
        ax.grid(alpha=0.3)
        osi = ax.twinx()
        osi.plot(block["z"], [np.nan if v is None else v for v in cycle["osi"]], "C3.-", label="OSI")
        osi.set_ylim(-0.02, 0.52)
        osi.set_ylabel("OSI", color="C3")
    save_figure(fig, path)


def plot_cycles(run, block: Mapping, path: Path) -> None:
    """Each pressure of the ``cycles`` block over each complete cycle, overlaid against the time into the cycle
    (mmHg), and the largest relative change of the cycle summaries from the cycle before."""
    cycles = block["cycles"]
    names = [n for n in cycles[0].get("pressure", {}) if n in run.series]
    changes = [(c["index"], c.get("max_change")) for c in cycles if c.get("max_change") is not None]
    panels = len(names) + bool(changes)
    fig = Figure(figsize=(8, 1.2 + 2.4 * max(panels, 1)), layout="constrained")
    axes = fig.subplots(max(panels, 1), 1, squeeze=False)[:, 0]
    t = run.t
    for ax, name in zip(axes, names):
        for c in cycles:
            rows = inside(t, c["start"], c["end"], block["period"])
            ax.plot(t[rows] - c["start"], run.series[name][rows] / MMHG, label=f"cycle {c['index'] + 1}")
        ax.set_ylabel("p (mmHg)")
        ax.set_title(name, fontsize="medium")
        ax.grid(alpha=0.3)
        ax.legend(fontsize="small", ncols=min(len(cycles), 4))
    if names:
        axes[len(names) - 1].set_xlabel("time into the cycle (s)")
    if changes:
        ax = axes[-1]
        index, change = zip(*changes)
        ax.semilogy(np.array(index) + 1, np.maximum(np.abs(change), 1e-16), "o-")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_xlabel("cycle")
        ax.set_ylabel("max |relative change|")
        ax.set_title("change of the cycle's pressures, stroke volume and distensibility from the cycle before",
                     fontsize="medium")
        ax.grid(alpha=0.3)
    save_figure(fig, path)
