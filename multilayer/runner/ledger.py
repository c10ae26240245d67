"""The discrete energy ledger of theory §7, closed step by step.

Each step hands in three groups of terms, by column name:

* ``energy``: the stored energy at tⁿ⁺¹ (kinetic and elastic, per part);
* ``work``: energy put in during the step (pressure work);
* ``dissipation``: energy taken out during the step (viscous and numerical).

The ledger checks Eⁿ⁺¹ − Eⁿ − work + dissipation = 0.  Every term is an
identity of the discrete scheme, so the residual is round-off.
"""

from __future__ import annotations

from collections.abc import Mapping

TINY = 1e-300


def close(energy: Mapping[str, float], previous_total: float,
          work: Mapping[str, float], dissipation: Mapping[str, float]) -> dict[str, float]:
    """One ledger row: every term plus ``energy.total``, ``energy.residual``, ``energy.relative_residual``.

    The relative residual is scaled by the largest quantity that enters it.

    >>> row = close({"kinetic": 1.5}, 1.0, {"work.p": 1.0}, {"dissipation.v": 0.5})
    >>> row["energy.residual"], row["energy.relative_residual"]
    (0.0, 0.0)
    """
    total = float(sum(energy.values()))
    w = float(sum(work.values()))
    d = float(sum(dissipation.values()))
    residual = total - previous_total - w + d
    scale = max(abs(total), abs(previous_total), abs(w), abs(d), TINY)
    return {
        **{k: float(v) for k, v in energy.items()},
        **{k: float(v) for k, v in work.items()},
        **{k: float(v) for k, v in dissipation.items()},
        "energy.total": total,
        "energy.residual": residual,
        "energy.relative_residual": abs(residual) / scale,
    }
