"""``kinematic-splitting``: the kinematically coupled scheme (SCHEME §3).

Each step is a Lie splitting of the coupled problem:

A1 — the structure step: all layers together, fluid frozen, backward
     Euler with a matrix factorized once; the thin layer's old velocity
     vⁿ is the fluid's interface trace (the kinematic condition).
A2 — the fluid step on the domain of ηⁿ, with the ALE velocity from
     v^{n+½}, and the inertia of the thin layer at the interface as the
     Robin term ρ₁h ∫ (v − v^{n+½})/Δt ψ: no sub-iterations and no
     added-mass instability.

The ledger of the whole step is the sum of the A1 and A2 identities
(SCHEME §4): Eⁿ⁺¹ − Eⁿ − work + dissipation = 0 to round-off.
"""

from __future__ import annotations

from collections.abc import Iterator

import scipy.sparse as sp

from multilayer import ledger
from multilayer.hookspecs import hookimpl
from multilayer.interfaces import Coupler, StepReport
from multilayer.records import CouplerPlugin
from multilayer_plugins.channel.ledger import ledger_groups
from multilayer.structure import StructureStep
from multilayer.wall import LUMEN



class KinematicSplitting(Coupler):
    name = "kinematic-splitting"
    loads = ("inlet", "outlet", "external")

    def check_case(self, case) -> list[str]:
        problems = super().check_case(case)
        if case.fluid is None:
            problems.append("kinematic-splitting couples a fluid to the wall: declare [fluid], "
                            "or choose the coupler 'structure-only'")
        if not case.layers:
            problems.append("kinematic-splitting needs a wall: declare [[layers]], or choose 'fluid-only'")
        elif not case.layers[0].thin:
            problems.append(f"kinematic-splitting needs a thin layer at the fluid interface, but layers[0] is "
                            f"'{case.layers[0].model}' (thick): put a thin layer (e.g. 'koiter-shell' or "
                            f"'wave-membrane') first in [[layers]]")
        if case.loads.wall_motion is not None:
            problems.append("loads.wall_motion prescribes the wall, which kinematic-splitting computes: "
                            "remove it, or choose the coupler 'fluid-only' without [[layers]]")
        return problems

    def prepare(self, scene) -> None:
        scene.setup_fluid("coupled")
        scene.wall_state.v = scene.wall.prolongations[LUMEN].T @ scene.wall_state.V
        scene.fluid_eta = scene.eta(LUMEN)

    def evolve(self, scene) -> Iterator[StepReport]:
        case, fluid, dt, wall = scene.case, scene.fluid, scene.dt, scene.wall
        a1 = StructureStep(scene.stack, dt, scene.stats, case.solver, fluid_line=LUMEN)
        robin_mass = self.robin_mass(scene)
        unit_outer = wall.line_load(wall.outer_line)
        structure_before = sum(a1.energy(scene.wall_state).values())
        previous = structure_before + fluid.kinetic_energy(scene.fluid_state, scene.fluid_eta)
        for n, t0, t1 in scene.windows():
            eta_n = scene.fluid_eta  # ηⁿ: the fluid step runs on the domain before the structure step
            # A1: structure, fluid frozen
            forces = {"external": -case.loads.external.average(t0, t1) * unit_outer}
            scene.wall_state, half, work, dissipation = a1.step(scene.wall_state, forces)
            a1_row = ledger.close(half, structure_before, work, dissipation)
            v_half = scene.wall_state.v
            # A2: fluid on the domain of ηⁿ, thin-layer inertia as the Robin term
            res = fluid.step(scene.fluid_state, eta_n, v_half,
                             case.loads.inlet.average(t0, t1), case.loads.outlet.average(t0, t1),
                             robin_mass=robin_mass)
            scene.fluid_state = res.state
            scene.wall_state.v = res.state.v
            scene.fluid_eta = scene.eta(LUMEN)
            stored_f, work_f, dissipation_f = ledger_groups(res.energy)
            stored_wall = a1.energy(scene.wall_state)
            structure_before = sum(stored_wall.values())
            stored = {**stored_wall, **stored_f}
            row = ledger.close(stored, previous, {**work, **work_f}, {**dissipation, **dissipation_f})
            # each sub-step's own identity, besides the total (SCHEME §4)
            row["energy.relative_residual.A1"] = a1_row["energy.relative_residual"]
            row["energy.relative_residual.A2"] = abs(res.energy["a2.residual"]) / max(res.energy["a2.scale"],
                                                                                      ledger.TINY)
            previous = row["energy.total"]
            yield StepReport(n + 1, t1, row)

    @staticmethod
    def robin_mass(scene) -> sp.csr_matrix:
        """ρ₁h ∫ v ψ of every thin layer on the fluid interface, in the line's numbering."""
        P = scene.wall.prolongations[LUMEN]
        masses = [scene.stack.matrices[p.index].mass for p in scene.wall.placements if p.line == LUMEN]
        return (P.T @ sum(masses[1:], masses[0]) @ P).tocsr()


@hookimpl
def multilayer_couplers():
    return [CouplerPlugin(name="kinematic-splitting", factory=KinematicSplitting,
                          doc="Kinematically coupled scheme: structure step, then fluid step with a Robin term.")]
