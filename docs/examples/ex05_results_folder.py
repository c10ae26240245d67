"""Example 5: write a results folder, read it back into arrays, plot η(z, t).

``ml.run(case, out)`` writes the folder ``multilayer run --out`` writes
(summary.json, series.csv, eta_lumen.csv); ``ml.read_results`` reads any
such folder back — one written by the command line, by a sweep, or by a
run that failed.  ``eta_lumen`` is η on the lumen at every vertex and every
step: the space-time picture of the pulse, drawn here with matplotlib.

Prints the peak η at z = 1 cm read from that field, in µm (about 488.2 on
this coarse mesh): the probe at z = 1 sits on a vertex, so the field and
the probe agree exactly.
"""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; drop this line in a notebook
import matplotlib.pyplot as plt
import numpy as np

import multilayer as ml

CASES = Path(__file__).resolve().parents[2] / "cases"
out = Path("results/ex05-pulse-koiter-thick")

case = ml.load_case(CASES / "pulse-koiter-thick.toml", {"mesh.nz": 30, "mesh.nr": 4, "time.end": 0.006})
ml.run(case, out)  # the same folder as: multilayer run ... --out results/ex05-... --no-plots

res = ml.read_results(out)  # later, or in another session
print(res)
z, t, eta = res.eta_lumen  # eta[i, j] = η(t[i], z[j])

fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
mesh = left.pcolormesh(z, 1e3 * t, 1e4 * eta, shading="nearest", cmap="RdBu_r")
fig.colorbar(mesh, ax=left, label="η (µm)")
left.set(xlabel="z (cm)", ylabel="t (ms)", title="η on the lumen")
for name, values in res.probes.items():
    if name.startswith("eta_"):
        right.plot(1e3 * res.t, 1e4 * values, label=name)
right.set(xlabel="t (ms)", ylabel="η (µm)", title="probes")
right.legend()
fig.savefig(out / "eta.png", dpi=100)
plt.close(fig)

j = int(np.argmin(np.abs(z - 1.0)))  # the vertex at z = 1 cm
peak_um = 1e4 * float(np.max(np.abs(eta[:, j])))
assert abs(peak_um - 1e4 * res.peaks["eta_z1"]) <= 1e-9 * peak_um
print(f"peak eta at z = {z[j]:g} cm from eta_lumen: {peak_um:.4f} um (figure: {out / 'eta.png'})")
