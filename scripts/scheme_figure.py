"""The figure of docs/scheme.md: the Koiter + thick pulse at Δt and Δt/8.

Runs ``cases/pulse-koiter-thick.toml`` twice (Δt = 1e-4 as bundled, and
Δt = 1.25e-5) with wall snapshots, then plots η at the probes over time
and the space–time map η(z, t) of the lumen line.  Prints the peak η at
each probe for both runs as JSON.

    python scripts/scheme_figure.py [OUT_DIR]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from multilayer.case.casefile import load_case
from multilayer.plugin.registry import Registry
from multilayer.results.reading import lumen_eta, read_series
from multilayer.runner.loop import run_case

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "cases" / "pulse-koiter-thick.toml"


def run(out: Path, dt: float, every: int) -> Path:
    registry = Registry.load()
    case = load_case(CASE, [f"time.dt={dt}", f"output.every={every}"], registry)
    result = run_case(case, out, registry)
    assert result.status == "ok", result.reason
    return out


def main(out_dir: Path) -> None:
    coarse = run(out_dir / "dt1e-4", 1e-4, 2)
    fine = run(out_dir / "dt1.25e-5", 1.25e-5, 16)
    fig = Figure(figsize=(11, 4.2))
    FigureCanvasAgg(fig)
    ax, ax2 = fig.subplots(1, 2)
    peaks = {}
    for folder, style, label in ((coarse, "-", "Δt = 1e-4"), (fine, "--", "Δt = 1.25e-5")):
        s = read_series(folder / "series.csv")
        peaks[label] = {}
        for i, z in enumerate((1, 2, 3, 4)):
            y = s[f"eta_z{z}"]
            peaks[label][f"z={z}"] = float(np.max(y))
            ax.plot(1e3 * s["t"], 1e4 * y, style, color=f"C{i}", label=f"z = {z} cm, {label}")
    ax.set_xlabel("t (ms)")
    ax.set_ylabel("η (µm)")
    ax.set_title("Lumen displacement at the probes")
    ax.legend(fontsize=7, ncol=2)
    z, t, eta = lumen_eta(coarse, 0.5)
    mesh = ax2.pcolormesh(z, 1e3 * t, 1e4 * eta, shading="nearest", cmap="viridis")
    fig.colorbar(mesh, ax=ax2, label="η (µm)")
    ax2.set_xlabel("z (cm)")
    ax2.set_ylabel("t (ms)")
    ax2.set_title("η(z, t), Δt = 1e-4")
    fig.tight_layout()
    fig.savefig(ROOT / "docs" / "figures" / "koiter-thick-pulse.png", dpi=110)
    print(json.dumps(peaks, indent=2))


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("results/scheme-figure"))
