"""The figures of one run, from its results folder alone: ``multilayer plot DIR`` and the end of ``run``.

* ``eta_spacetime.png`` — η(z, t) on the lumen line (from ``eta_lumen.csv``);
* ``probes.png`` — every probe against time, one panel per quantity;
* ``energy.png`` — the energy ledger: stored energy, cumulative work and
  dissipation, and the relative residual of every step;
* ``wss.png`` — the wall shear stress τ_w(z, t) (from ``wss_lumen.csv``) and, under a periodic load, TAWSS and
  OSI along the lumen over the last complete cycle (``summary.json`` ``wss``);
* ``cycles.png`` — under a periodic load, every pressure over each complete cycle, overlaid (mmHg), and the
  largest relative change of the cycle summaries from one cycle to the next (``summary.json`` ``cycles``);
* ``pressure_diameter.png`` — in a tube under a periodic load, the pressure against the lumen's diameter
  over the last complete cycle (mmHg, mm), one loop for every place with a ``p`` and an ``eta`` probe;
* ``pulse_wave.png`` — under a periodic load, the pressures over the last complete cycle with each one's
  foot, and the pulse-wave velocity foot to foot between them (``summary.json`` ``cycles``).

Made to be shown on a slide: fonts of 12 pt and more (:data:`SLIDE`), titles
wrapped to the figure's width rather than cut, a unit on every axis, and the
units a person reads (:func:`display`): displacements in µm, pressures in
mmHg (dyn/cm² on the right-hand axis), a tube's flow rates in mL/s.  The
data behind them stay CGS.

A figure replaces only a file the run owns (its folder's manifest lists it,
:func:`multilayer.results.folder.may_write`); a file of that name the run did
not write is kept, and the figure not drawn.  Every PNG is written to a
fresh temporary and renamed into place: a symbolic link is never followed.
"""

from __future__ import annotations

import logging
import textwrap
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from multilayer.plugin.units import MMHG
from multilayer.results.cycles import inside, pressure_diameter
from multilayer.results.files import atomic_file
from multilayer.results.folder import may_write
from multilayer.results.reading import lumen_eta, lumen_wss, read_run
from multilayer.results.readouts import QUANTITIES, TUBE_FLOW, unit_of

#: font sizes legible on a slide (points; a figure is 8 to 11 inches wide)
SLIDE = {"font.size": 12, "axes.titlesize": 13, "axes.labelsize": 12, "xtick.labelsize": 11,
         "ytick.labelsize": 11, "legend.fontsize": 10, "figure.titlesize": 14}
#: characters of a title per inch of its axes' width at :data:`SLIDE`'s title size
CHARACTERS_PER_INCH = 9.5
#: µm in a cm
MICRONS = 1e4


@contextmanager
def quiet_fonts() -> Iterator[None]:
    """matplotlib's font search says nothing on stderr inside: its fallbacks ('findfont: Font family … not
    found', for a log axis's mathtext as for the text) are no news to a user reading a run."""
    fonts = logging.getLogger("matplotlib.font_manager")
    level = fonts.level
    fonts.setLevel(logging.ERROR)
    try:
        yield
    finally:
        fonts.setLevel(level)


@contextmanager
def slide_style() -> Iterator[None]:
    """The figures' fonts (:data:`SLIDE`), for what is drawn inside, with :func:`quiet_fonts`."""
    with quiet_fonts(), matplotlib.rc_context(SLIDE):
        yield


def fit(text: str, inches: float) -> str:
    """``text`` wrapped into lines that fit a width of ``inches`` at the title size: a title is never cut.

    >>> print(fit("Pressure pulse in a three-layer artery: intima | media | adventitia", 4.0))
    Pressure pulse in a three-layer
    artery: intima | media | adventitia
    """
    return "\n".join(textwrap.wrap(text, max(12, int(CHARACTERS_PER_INCH * inches))) or [""])


def display(quantity: str, units: Mapping[str, str] | None = None) -> tuple[str, float, str]:
    """(symbol, factor, unit) a person reads a probe ``quantity`` in: the CGS value times ``factor`` is in
    ``unit``.  ``units`` are the run's integral units (``summary.json`` ``units``).

    >>> display("eta"), display("p")[0], round(display("p")[1] * MMHG, 12), display("p")[2]
    (('η', 10000.0, 'µm'), 'p', 1.0, 'mmHg')
    >>> display("flow_rate", {"flow_rate": "cm³/s"}), display("flow_rate"), display("u_z")
    (('Q', 1.0, 'mL/s'), ('Q', 1.0, 'cm²/s'), ('u_z', 1.0, 'cm/s'))
    """
    symbol = QUANTITIES.get(quantity, (quantity,))[0].split(",")[0]
    unit = unit_of(quantity, units)
    if unit == "cm":
        return symbol, MICRONS, "µm"
    if quantity == "p":
        return symbol, 1.0 / MMHG, "mmHg"
    if unit == TUBE_FLOW:
        return symbol, 1.0, "mL/s"
    return symbol, 1.0, unit


def label_axis(ax: Axes, quantity: str, units: Mapping[str, str] | None = None) -> float:
    """The y label of ``quantity`` in the unit a person reads (a pressure also in dyn/cm², on the right); the
    factor from CGS to it."""
    symbol, factor, unit = display(quantity, units)
    ax.set_ylabel(f"{symbol} ({unit})")
    if quantity == "p":
        right = ax.secondary_yaxis("right", functions=(lambda mmhg: mmhg * MMHG, lambda dyn: dyn / MMHG))
        right.set_ylabel("p (dyn/cm²)")
    return factor


def plot_run(folder: Path | str) -> list[Path]:
    """Write the run's figures into ``folder``; returns their paths (those that could be made).

    A figure whose file is in the folder but not the run's (:func:`~multilayer.results.folder.may_write`)
    is not drawn: that file is kept.
    """
    with quiet_fonts():
        return _plot_run(Path(folder))


def _plot_run(folder: Path) -> list[Path]:
    run = read_run(folder.name, folder)
    written = []
    radius = (run.case.get("geometry") or {}).get("radius")
    field = lumen_eta(folder, radius) if radius is not None and may_write(folder, "eta_spacetime.png") else None
    if field is not None:
        plot_spacetime({folder.name: field}, folder / "eta_spacetime.png", title=run.case.get("title") or None)
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
        loops = pressure_diameter_loops(run, block) if radius is not None else []
        if loops and may_write(folder, "pressure_diameter.png"):
            plot_pressure_diameter(loops, block["cycles"][-1], folder / "pressure_diameter.png")
            written.append(folder / "pressure_diameter.png")
        if block["cycles"][-1].get("pulse_wave_velocity") and may_write(folder, "pulse_wave.png"):
            plot_pulse_wave(run, block, folder / "pulse_wave.png")
            written.append(folder / "pulse_wave.png")
    return written


def _where(p) -> str:
    return f"z = {p['z']:g} cm" + (f", r = {p['r']:g} cm" if p.get("r") is not None else "")


def plot_probes(run, path: Path) -> Figure:
    """One panel per probe quantity, every probe of that quantity against t, in the unit a person reads
    (:func:`display`); returns the figure."""
    groups: dict[str, list] = {}
    for p in run.probes:
        groups.setdefault(p["quantity"], []).append(p)
    with slide_style():
        fig = Figure(figsize=(9, 1.4 + 2.8 * len(groups)), layout="constrained")
        axes = fig.subplots(len(groups), 1, sharex=True, squeeze=False)[:, 0]
        for ax, (quantity, probes) in zip(axes, groups.items()):
            factor = label_axis(ax, quantity, _units(run))
            for p in probes:
                ax.plot(run.t, factor * run.series[p["name"]], label=f"{p['name']} ({_where(p)})")
            ax.set_title(fit(QUANTITIES.get(quantity, (quantity,))[0], 7.0))
            ax.grid(alpha=0.3)
            ax.legend(ncols=2 if len(probes) > 3 else 1)
        axes[-1].set_xlabel("t (s)")
        save_figure(fig, path)
    return fig


def _units(run) -> dict[str, str]:
    """The units of the run's integrals as its geometry gave them (``summary.json`` ``units``; per unit depth
    for a run written before they were recorded)."""
    return (getattr(run, "summary", None) or {}).get("units") or {}


def plot_energy(run, path: Path) -> Figure:
    """Stored energy, cumulative work and dissipation (erg per unit depth, or in the geometry's units), and
    each step's residual; returns the figure."""
    s, t = run.series, run.t
    work = np.cumsum(sum((s[k] for k in s if k.startswith("work.")), np.zeros_like(t)))
    dissipation = np.cumsum(sum((s[k] for k in s if k.startswith("dissipation.")), np.zeros_like(t)))
    stored = s["energy.total"]
    initial = stored[0] - (work[0] - dissipation[0])  # E⁰ = E¹ − work¹ + dissipation¹ (the ledger of step 1)
    with slide_style():
        fig = Figure(figsize=(9, 7), layout="constrained")
        top, bottom = fig.subplots(2, 1, sharex=True)
        top.plot(t, stored, label="stored energy E")
        top.plot(t, initial + work, label="E⁰ + cumulative work")
        top.plot(t, dissipation, label="cumulative dissipation")
        top.set_ylabel(f"energy ({_units(run).get('energy', 'erg/cm')})")
        top.set_title(fit("energy ledger: E = E⁰ + work − dissipation every step", 7.5))
        top.grid(alpha=0.3)
        top.legend()
        residual = np.maximum(s.get("energy.relative_residual", np.zeros_like(t)), 1e-300)
        bottom.semilogy(t, residual, ".", ms=4)
        bottom.set_ylabel("|residual| / scale (–)")
        bottom.set_xlabel("t (s)")
        bottom.set_title(fit("relative residual of each step's energy identity", 7.5))
        bottom.grid(alpha=0.3)
        save_figure(fig, path)
    return fig


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


def plot_spacetime(fields: Mapping[str, tuple[np.ndarray, np.ndarray, np.ndarray] | None], path: Path,
                   title: str | None = None) -> Figure:
    """η(z, t) in µm per run side by side, on one colour scale; returns the figure.

    A field of both signs gets a symmetric diverging scale (white at η = 0); one that keeps its sign (a wall
    inflated by ``initial.pressure``) a sequential one from its least to its largest value, so that the
    pulse shows on top of the offset.  ``title`` (the case's) is wrapped above the panels.
    """
    labels = list(fields) or ["(none)"]
    # the columns a layer's pinned end holds at 0 for ever would stretch a sequential scale down to 0: left out
    values = [f[2][:, np.any(f[2] != 0.0, axis=0)] for f in fields.values() if f is not None]
    values = [v for v in values if v.size and np.isfinite(v).any()]
    low = min((float(np.nanmin(v)) for v in values), default=0.0) * MICRONS
    high = max((float(np.nanmax(v)) for v in values), default=0.0) * MICRONS
    if low < 0.0 < high or low == high:
        peak = max(abs(low), abs(high)) or 1.0
        scale = {"cmap": "RdBu_r", "vmin": -peak, "vmax": peak}
    else:
        scale = {"cmap": "viridis", "vmin": low, "vmax": high}
    width = 1.6 + 3.6 * len(labels)
    with slide_style():
        fig = Figure(figsize=(width, 5.2), layout="constrained")
        axes = fig.subplots(1, len(labels), sharey=True, squeeze=False)[0]
        image = None
        for ax, label in zip(axes, labels):
            field = fields.get(label)
            ax.set_title(fit(label, 3.2))
            ax.set_xlabel("z (cm)")
            if field is None:
                ax.text(0.5, 0.5, "no snapshots", ha="center", va="center", transform=ax.transAxes)
                continue
            z, t, eta = field
            image = ax.imshow(MICRONS * eta, origin="lower", aspect="auto", extent=(*_edges(z), *_edges(t)),
                              interpolation="nearest", **scale)
        axes[0].set_ylabel("t (s)")
        if image is not None:
            fig.colorbar(image, ax=list(axes), label="η (µm)")
        if title:
            fig.suptitle(fit(title, width - 1.0))
        save_figure(fig, path)
    return fig


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


def pressure_diameter_loops(run, block: Mapping) -> list[dict]:
    """The pressure–diameter loop (:func:`~multilayer.results.cycles.pressure_diameter`) over the last complete
    cycle of ``block`` at every place with a ``p`` probe and an ``eta`` probe on the lumen (the first of each
    at that z), with ``z`` and the two probes' names; none but in a tube (its diameter is 2(R + η))."""
    if _units(run).get("flow_rate") != TUBE_FLOW:
        return []
    cycle, radius = block["cycles"][-1], run.case["geometry"]["radius"]
    out = []
    for p in run.probes:
        eta = next((e for e in run.probes if e["quantity"] == "eta" and not e.get("line") and e["z"] == p["z"]),
                   None)
        if p["quantity"] != "p" or eta is None or any(loop["z"] == p["z"] for loop in out):
            continue
        loop = pressure_diameter(run.t, run.series[p["name"]], run.series[eta["name"]], radius, cycle["start"],
                                 cycle["end"], block["period"])
        out.append({"z": p["z"], "pressure_probe": p["name"], "eta_probe": eta["name"], **loop})
    return out


def plot_pressure_diameter(loops: list[dict], cycle: Mapping, path: Path) -> Figure:
    """The pressure (mmHg) against the lumen's diameter (mm) over ``cycle``, one loop per place (``loops``,
    :func:`pressure_diameter_loops`), each with its distension in the legend; returns the figure."""
    with slide_style():
        fig = Figure(figsize=(8, 6), layout="constrained")
        ax = fig.subplots()
        for loop in loops:
            change = loop["diameter_max"] / loop["diameter_min"] - 1.0
            ax.plot(loop["diameter"], loop["pressure"], label=f"z = {loop['z']:g} cm ({loop['pressure_probe']}, "
                    f"{loop['eta_probe']}): ΔD/D = {change:.1%}")
        ax.set_xlabel("lumen diameter D (mm)")
        ax.set_ylabel("p (mmHg)")
        ax.set_title(fit(f"pressure against diameter over the cycle {cycle['start']:g}–{cycle['end']:g} s", 7.5))
        ax.grid(alpha=0.3)
        ax.legend()
        save_figure(fig, path)
    return fig


def plot_pulse_wave(run, block: Mapping, path: Path) -> Figure:
    """The pressures of the last complete cycle that gave its pulse-wave velocity, each with its foot (a dot),
    against the time into the cycle; the velocity (or why there is none) in the title; returns the figure."""
    cycle = block["cycles"][-1]
    speed = cycle["pulse_wave_velocity"]
    rows = inside(run.t, cycle["start"], cycle["end"], block["period"])
    with slide_style():
        fig = Figure(figsize=(9, 5.5), layout="constrained")
        ax = fig.subplots()
        for i, (name, foot) in enumerate(speed["feet"].items()):
            if name not in run.series:
                continue
            t, p = run.t[rows] - cycle["start"], run.series[name][rows] / MMHG
            ax.plot(t, p, color=f"C{i}", label=f"{name} (z = {foot['z']:g} cm)")
            if foot["time"] is not None:
                at = foot["time"] - cycle["start"]
                ax.plot([at], [np.interp(at, t, p)], "o", color=f"C{i}", ms=7)
        label_axis(ax, "p")
        ax.set_xlabel("time into the cycle (s)")
        title = (f"pulse-wave velocity {speed['m_s']:.3g} m/s, foot to foot (dots: the feet)" if speed["m_s"] is not None
                 else f"no pulse-wave velocity: {speed['reason']}")
        ax.set_title(fit(f"{title}; cycle {cycle['start']:g}–{cycle['end']:g} s", 7.5))
        ax.grid(alpha=0.3)
        ax.legend(ncols=2 if len(speed["feet"]) > 3 else 1)
        save_figure(fig, path)
    return fig
