"""``multilayer study``: speed against error of couplers × Δt (× mesh), collected from the runs' folders.

Plan → execute → collect:

* :func:`multilayer.campaign.planning.plan` turns ``--couplers`` and every
  ``--vary`` into a grid of runs, each a
  :class:`~multilayer.campaign.variants.Variant` (case file + overrides) with its
  results folder ``OUT/<coupler>/<key=value>/...``;
* :func:`multilayer.campaign.planning.run_planned` runs them
  (:func:`multilayer.campaign.executor.execute`: here with ``--jobs 1``, else on
  Dask), each into an ordinary results folder
  (:func:`multilayer.campaign.variants.run_variant`);
* :func:`collect` measures everything from those folders alone
  (:func:`multilayer.results.reading.read_run`): errors against a reference,
  observed orders, the Pareto front of wall time against error, the cost of
  reaching a target error; :func:`study_data` is the whole ``study.json``,
  which :mod:`multilayer.campaign.study_report` writes with ``study.md`` and
  the figures.

The command line (its options, messages and exit codes) is
:mod:`multilayer.commands.study`.

The measurements are pure functions of numbers and arrays, in
:mod:`multilayer.campaign.accuracy` (:func:`~multilayer.campaign.accuracy.relative_linf`,
:func:`~multilayer.campaign.accuracy.probe_errors`,
:func:`~multilayer.campaign.accuracy.observed_orders`,
:func:`~multilayer.campaign.accuracy.pareto_front`,
:func:`~multilayer.campaign.accuracy.richardson`,
:func:`~multilayer.campaign.accuracy.richardson_order`,
:func:`~multilayer.campaign.accuracy.cost_to_target`).  See ``docs/study.md``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import attrs

from multilayer.campaign.accuracy import (
    cost_to_target,
    observed_orders,
    pareto_front,
    probe_errors,
    richardson,
    richardson_order,
)
from multilayer.campaign.planning import REFERENCE, CouplerChoice, Planned
from multilayer.case.schema import ADAPTIVE_KEYS
from multilayer.plugin.problems import Problem, did_you_mean
from multilayer.results.reading import RunData, dof_counts

#: target peak errors of the cost table
TARGETS = (0.05, 0.01)
#: the coupler the costs are also given relative to, when it is in the study
BASELINE = "kinematic-splitting"
#: key paths a compared run may differ in from the reference (the reference may stop earlier: ``time.end``)
#: the keys of adaptive steps: a run with ``time.tolerance`` is compared by its tolerance, not by Δt
ADAPTIVE = ("tolerance", *ADAPTIVE_KEYS)
FREE_KEYS = ("title", "coupler", "time.dt", "time.end", "mesh", "output.every", *(f"time.{k}" for k in ADAPTIVE))
#: key paths in which the runs of the reference's own Δt sequence differ from it (Richardson)
SIBLING_KEYS = ("title", "time.dt", "output.every")
#: an observed order outside this range is not trusted for Richardson: the formal order is used
ORDER_RANGE = (0.5, 4.0)


def case_differences(a: Any, b: Any, free: Sequence[str] = (), path: str = "") -> list[str]:
    """Key paths at which two resolved cases differ, leaving out ``free`` paths (and what is under them).

    >>> case_differences({"time": {"dt": 1, "end": 2}, "fluid": {"mu": 1}, "layers": [{"E": 1}]},
    ...                  {"time": {"dt": 2, "end": 2}, "fluid": {"mu": 3}, "layers": [{"E": 2}]}, ["time.dt"])
    ['fluid.mu', 'layers[0].E']
    """
    if path in free:
        return []
    if isinstance(a, Mapping) and isinstance(b, Mapping):
        return [d for k in sorted(set(a) | set(b), key=str)
                for d in case_differences(a.get(k), b.get(k), free, f"{path}.{k}" if path else str(k))]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in case_differences(x, y, free, f"{path}[{i}]")]
    return [] if a == b else [path]

# -- collecting ------------------------------------------------------------------


def scheme_order(summary: Mapping[str, Any]) -> int | float:
    """The formal order of a run's coupler: ``summary["scheme"]["order"]``, or 1 when not written.

    >>> scheme_order({"scheme": {"name": "crank-nicolson", "order": 2}}), scheme_order({})
    (2, 1)
    """
    order = (summary.get("scheme") or {}).get("order")
    return order if isinstance(order, int | float) and not isinstance(order, bool) and order > 0 else 1


def eta_errors(run: RunData, reference: RunData, names: Sequence[str] | None = None) -> dict[str, dict[str, Any]]:
    """:func:`probe_errors` at every ``eta`` probe of ``run`` that the reference has too (same name).

    ``names`` (``--probes``) keeps only those probes.
    """
    ref_probes = {p["name"] for p in reference.probes if p["quantity"] == "eta"}
    return {p["name"]: {"z": p["z"], "line": p.get("line"),
                        **probe_errors(run.t, run.series[p["name"]], reference.t, reference.series[p["name"]])}
            for p in run.probes if p["quantity"] == "eta" and p["name"] in ref_probes
            and (names is None or p["name"] in names)}


def _worst(probes: Mapping[str, Mapping[str, Any]], key: str) -> float | None:
    values = [e[key] for e in probes.values() if e.get(key) is not None]
    return max(values) if values else None


def _row(planned: Planned, run: RunData, position: int) -> dict[str, Any]:
    s, case = run.summary, run.case
    dofs = dof_counts(s)
    return {
        "label": planned.label,
        "folder": planned.folder,
        "coupler": planned.coupler,
        "coupler_index": position,  # in --couplers: breaks ties between couplers of one order
        "model": (case.get("coupler") or {}).get("model"),
        "values": dict(planned.values),
        "overrides": list(planned.variant.overrides),
        "status": s.get("status", "failed"),
        "reason": s.get("reason", "" if s else "no summary.json written"),
        "wall_time_s": s.get("wall_time_s"),
        "steps": s.get("steps"),
        "dofs": dofs,
        "dofs_total": sum(dofs.values()) if dofs else None,
        "dt": (case.get("time") or {}).get("dt"),
        "tolerance": (case.get("time") or {}).get("tolerance"),  # adaptive steps (Δt is then the first step)
        "nz": (case.get("mesh") or {}).get("nz"),
        "order": scheme_order(s),
        "reference": False,
        "compared": False,
        "not_compared": "",
        "probes": {},
        "error": None,
        "peak_error": None,
    }


def choose_reference(rows: Sequence[Mapping[str, Any]]) -> int | None:
    """Index of the finest ok run (smallest Δt, then largest nz) of the highest-order coupler.

    Ties between couplers of one order go to the first in ``--couplers``.

    >>> rows = [{"status": "ok", "order": 1, "coupler_index": 0, "dt": 1e-5, "nz": 10},
    ...         {"status": "ok", "order": 2, "coupler_index": 1, "dt": 1e-4, "nz": 10},
    ...         {"status": "ok", "order": 2, "coupler_index": 1, "dt": 5e-5, "nz": 10},
    ...         {"status": "failed", "order": 2, "coupler_index": 1, "dt": 1e-6, "nz": 10}]
    >>> choose_reference(rows)
    2
    """
    ok = [i for i, r in enumerate(rows) if r["status"] == "ok" and r["dt"] is not None and not r.get("tolerance")]
    if not ok:
        return None
    return min(ok, key=lambda i: (-rows[i]["order"], rows[i]["coupler_index"], rows[i]["dt"], -(rows[i]["nz"] or 0)))


def _measured(row: Mapping[str, Any]) -> bool:
    return row["status"] == "ok" and not row["reference"] and row["error"] is not None


def dt_sequences(rows: Sequence[dict[str, Any]], by: str = "dt") -> dict[tuple, list[dict[str, Any]]]:
    """Runs of one coupler with the same values of every varied key but time.dt, coarse Δt first.

    ``by = "tolerance"``: the adaptive runs instead, by the same values of every key but time.tolerance
    and time.dt (their first step), loose tolerance first.
    """
    groups: dict[tuple, list[dict[str, Any]]] = {}
    for row in rows:
        if _measured(row) and bool(row.get("tolerance")) == (by == "tolerance"):
            key = (row["coupler"], tuple((k, v) for k, v in row["values"].items()
                                         if k not in ("time.dt", f"time.{by}")))
            groups.setdefault(key, []).append(row)
    return {k: sorted(g, key=lambda r: -r[by]) for k, g in groups.items()}


def calibration_table(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The adaptive runs: error against tolerance (their ratio should stay near 1), steps and wall time."""
    return [{"coupler": coupler, "group": dict(others), "run": r["label"], "tolerance": r["tolerance"],
             "error": r["error"], "peak_error": r["peak_error"], "ratio": r["error"] / r["tolerance"],
             "steps": r["steps"], "wall_time_s": r["wall_time_s"]}
            for (coupler, others), group in dt_sequences(rows, "tolerance").items() for r in group]


def orders_table(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The observed orders of ``error`` and ``peak_error`` between successive Δt of each group."""
    out = []
    for (coupler, others), group in dt_sequences(rows).items():
        dts = [r["dt"] for r in group]
        if len(set(dts)) < len(dts):
            continue  # the same Δt twice (a --set fixed it): no order
        for pair, p, q in zip(zip(group, group[1:]), observed_orders(dts, [r["error"] for r in group]),
                              observed_orders(dts, [r["peak_error"] for r in group])):
            out.append({"coupler": coupler, "group": dict(others), "coarse": pair[0]["label"],
                        "fine": pair[1]["label"], "dt_coarse": pair[0]["dt"], "dt_fine": pair[1]["dt"],
                        "error_order": p, "peak_error_order": q})
    return out


def _between(a: RunData, b: RunData, names: Sequence[str] | None = None) -> dict[str, float | None]:
    """``error`` and ``peak_error`` of ``a`` measured against ``b``."""
    probes = eta_errors(a, b, names)
    return {"error": _worst(probes, "relative_linf"), "peak_error": _worst(probes, "peak_error")}


def reference_error(reference: RunData, ref_order: float, rows: Sequence[Mapping[str, Any]],
                    runs: Mapping[str, RunData], names: Sequence[str] | None = None) -> dict[str, Any]:
    """Richardson's estimate of the reference's own ``error`` and ``peak_error``.

    From the two finest ok runs whose case is the reference's but for Δt
    (the reference itself when it is a run of the study): the difference d
    of the finest from the next, r their Δt ratio, p the order observed with
    a third run (:func:`richardson_order`) when it lies in
    :data:`ORDER_RANGE`, else the formal order.  The estimate
    d/(r^p − 1) is that of the finest run; a reference finer still is scaled
    by (Δt_ref/Δt_finest)^p.
    """
    by_dt: dict[float, Mapping[str, Any]] = {}
    for r in sorted(rows, key=lambda r: not r["reference"]):  # the reference first: it stands for its Δt
        if (r["status"] == "ok" and r["dt"] is not None
                and not case_differences(reference.case, runs[r["label"]].case, SIBLING_KEYS)):
            by_dt.setdefault(r["dt"], r)
    siblings = sorted(by_dt.values(), key=lambda r: -r["dt"])
    if len(siblings) < 2:
        return {"estimated": False, "note": "fewer than two ok runs of the reference's case that differ from it "
                                            "only in Δt"}
    chain = siblings[-3:]
    fine, coarse = chain[-1], chain[-2]
    ratio = coarse["dt"] / fine["dt"]
    dt_ref = (reference.case.get("time") or {}).get("dt", fine["dt"])
    d_fine = _between(runs[coarse["label"]], runs[fine["label"]], names)
    d_coarse = _between(runs[chain[0]["label"]], runs[coarse["label"]], names) if len(chain) == 3 else None
    out: dict[str, Any] = {"estimated": True, "fine": fine["label"], "coarse": coarse["label"],
                           "third": chain[0]["label"] if len(chain) == 3 else None, "ratio": ratio,
                           "formal_order": ref_order}
    for key in ("error", "peak_error"):
        observed = None
        if d_coarse is not None and d_coarse[key] is not None and d_fine[key] is not None:
            observed = richardson_order([r["dt"] for r in chain], d_coarse[key], d_fine[key])
        trusted = observed is not None and ORDER_RANGE[0] <= observed <= ORDER_RANGE[1]
        p = observed if trusted else ref_order
        scale = (dt_ref / fine["dt"]) ** p
        estimate = None if d_fine[key] is None else richardson(d_fine[key], ratio, p) * scale
        out[key] = {"difference": d_fine[key], "observed_order": observed, "order": p,
                    "order_from": "observed" if trusted else "formal", "scale": scale, "estimate": estimate}
    return out


def cost_table(rows: Sequence[dict[str, Any]], orders: Sequence[Mapping[str, Any]],
               couplers: Sequence[CouplerChoice]) -> list[dict[str, Any]]:
    """Per coupler and target peak error: :func:`cost_to_target`, and the ratio to :data:`BASELINE`'s."""
    out = []
    for choice in couplers:
        own = [r for r in rows if r["coupler"] == choice.label and _measured(r) and r["peak_error"] is not None
               and r["wall_time_s"] is not None and not r.get("tolerance")]
        finest = min(range(len(own)), key=lambda i: (own[i]["dt"], -(own[i]["nz"] or 0))) if own else None
        order = next((o["peak_error_order"] for o in orders if own and o["fine"] == own[finest]["label"]), None)
        for target in TARGETS:
            cost = cost_to_target([r["wall_time_s"] for r in own], [r["peak_error"] for r in own], target,
                                  finest, order)
            out.append({"coupler": choice.label, "model": choice.model, "target": target,
                        "how": cost["how"], "wall_time_s": cost["wall_time_s"], "order": cost["order"],
                        "run": None if cost["run"] is None else own[cost["run"]]["label"]})
    baseline = next((c.label for c in couplers if c.model == BASELINE), None)
    for entry in out:
        base = next((e for e in out if e["coupler"] == baseline and e["target"] == entry["target"]), None)
        ok = base is not None and base["wall_time_s"] and entry["wall_time_s"] is not None
        entry["ratio_to_baseline"] = entry["wall_time_s"] / base["wall_time_s"] if ok else None
    return out


def collect(planned: Sequence[Planned], runs: Mapping[str, RunData], couplers: Sequence[CouplerChoice],
            reference: RunData | None = None, probes: Sequence[str] | None = None) -> dict[str, Any]:
    """Every number of ``study.json``, from the results folders read back (``runs`` by label).

    ``reference`` is the ``--reference`` run; without it the reference is
    :func:`choose_reference`'s.
    """
    index = {c.label: i for i, c in enumerate(couplers)}
    rows = [_row(p, runs[p.label], index[p.coupler]) for p in planned]
    if reference is not None:
        ref_order = scheme_order(reference.summary)
        ref_info = {"label": REFERENCE, "folder": REFERENCE, "source": "--reference",
                    "status": reference.summary.get("status", "failed")}
    else:
        i = choose_reference(rows)
        reference = None if i is None else runs[rows[i]["label"]]
        ref_order = None if i is None else rows[i]["order"]
        ref_info = {"label": None if i is None else rows[i]["label"],
                    "folder": None if i is None else rows[i]["folder"], "source": "finest run",
                    "status": None if i is None else "ok"}
        if i is not None:
            rows[i]["reference"] = True
    usable = reference is not None and reference.summary.get("status") == "ok"
    if reference is not None:
        ref_case = reference.case
        ref_info.update({"coupler": ref_case.get("coupler"), "dt": (ref_case.get("time") or {}).get("dt"),
                         "nz": (ref_case.get("mesh") or {}).get("nz"), "order": ref_order,
                         "wall_time_s": reference.summary.get("wall_time_s")})
    for row in rows:
        if row["reference"] or row["status"] != "ok" or not usable:
            continue
        run = runs[row["label"]]
        differs = case_differences(reference.case, run.case, FREE_KEYS)
        if differs:
            row["not_compared"] = "its case differs from the reference's at " + ", ".join(differs)
            continue
        row["compared"] = True
        row["probes"] = eta_errors(run, reference, probes)
        row["error"] = _worst(row["probes"], "relative_linf")
        row["peak_error"] = _worst(row["probes"], "peak_error")
    orders = orders_table(rows)
    measured = [r for r in rows if _measured(r) and r["wall_time_s"] is not None]
    front = pareto_front([r["wall_time_s"] for r in measured], [r["error"] for r in measured])
    ref_info["richardson"] = (reference_error(reference, ref_order, rows, runs, probes) if usable
                              else {"estimated": False, "note": "no ok reference"})
    return {
        "reference": ref_info,
        "space_error_included": usable and any(r["compared"] and r["nz"] != ref_info["nz"] for r in rows),
        "runs": rows,
        "orders": orders,
        "adaptive": calibration_table(rows),
        "pareto": sorted((measured[i]["label"] for i in front),
                         key=lambda label: next(r["wall_time_s"] for r in measured if r["label"] == label)),
        "cost_to_target": cost_table(rows, orders, couplers),
    }


def unknown_probes(names: Sequence[str], runs: Mapping[str, RunData]) -> list[Problem]:
    """A problem at ``--probes`` for each name that is not an η probe of any of the runs.

    >>> case = {"output": {"probes": [{"name": "eta_mid", "quantity": "eta"}]}}
    >>> run = RunData("a", Path("a"), {"case": case}, {"eta_mid": []})
    >>> [str(p) for p in unknown_probes(["eta_mid", "eta_mdi"], {"a": run})]
    ["--probes = 'eta_mdi': not an η probe of these runs; did you mean 'eta_mid'?"]
    """
    known = {p["name"] for r in runs.values() for p in r.probes if p["quantity"] == "eta"}
    return [Problem("--probes", name, "not an η probe of these runs",
                    did_you_mean(name, sorted(known)) or f"η probes: {', '.join(sorted(known))}")
            for name in names if name not in known]


def study_data(planned: Sequence[Planned], runs: Mapping[str, RunData], couplers: Sequence[CouplerChoice],
               axes: Sequence[tuple[str, Sequence[str]]], probes: Sequence[str] | None, *, command: str,
               case_file: Path, overrides: Sequence[str]) -> dict[str, Any]:
    """The whole of ``study.json``: what was asked (the command line, the case, the grid), then :func:`collect`.

    ``runs`` holds every planned run by label, and the ``--reference`` run
    under :data:`~multilayer.campaign.planning.REFERENCE` when there is one.
    """
    data = {
        "command": command,
        "case_file": str(case_file),
        "title": next((r.case.get("title", "") for r in runs.values() if r.case), ""),
        "overrides": list(overrides),
        "couplers": [attrs.asdict(c) for c in couplers],
        "vary": [{"key": k, "values": v} for k, v in axes],
        "targets": list(TARGETS),
        "probes": list(probes) if probes is not None else "every η probe",
        **collect(planned, runs, couplers, runs.get(REFERENCE), probes),
    }
    for row in data["runs"]:
        del row["coupler_index"]
    return data
