"""``kinematic-splitting``: the kinematically coupled scheme (theory §6) and its β and Crank–Nicolson variants.

Each step is a splitting of the coupled problem, no sub-iterations:

A1 — the structure step: all layers together, fluid frozen, a matrix
     factorized once; the thin layer's old velocity vⁿ is the fluid's
     interface trace (the kinematic condition).  With ``beta`` > 0 the thin
     layer is also loaded by β times the fluid's force on it, extrapolated
     from the previous steps (the β-scheme of Bukač, Čanić, Glowinski et al.).
A2 — the fluid step on the domain the structure step left, with a Robin
     term R(v̄ − V̄_Γ) on the wall's u_r rows, minus the β share of the force
     A1 already applied: no added-mass instability.  ``robin``:
     ``"inertia"`` takes R = (α₀/β₀)M/Δt, the thin layer's inertia (the
     paper's); ``"impedance"`` (the default) takes R = S_Γ, the whole wall
     step condensed on Γ (:func:`interface_impedance`), and
A3 — completes the wall's step under the fluid's force: one product with
     the kept A⁻¹P, after which the wall moves with the fluid (V̄_Γ = v̄)
     and the lumen's volume follows the flow through the ends.

``robin = "inertia"``, ``scheme = "backward-euler"``, ``beta = 0`` is the
scheme of the seed paper (first order).  ``scheme = "crank-nicolson"`` runs both sub-steps as
refactorized midpoint steps (a backward-Euler step of Δt/2, then
x^{n+1} = 2x̄ − xⁿ), the fluid on the midpoint domain (ηⁿ + η^{n+1})/2; with
``beta = 1`` the structure step sees the fluid's force at the previous
midpoint and the splitting error drops to second order in Δt (derivation
in docs/theory.md).

Under the paper's Robin term the energy identity of a step is the sum of
the A1 and A2 identities: the thin layer's kinetic energy after A1 is the
one A2 starts from, and the β force enters A1 and A2 with opposite signs,
leaving −Δt β τ̃·(V̄_Γ − v̄) as the column ``dissipation.beta`` (a term of
the scheme, of either sign, not work of a load: the energy bound
E ≤ E⁰ + work counts loads only).  Under the impedance it is A3's plus
A2's, the fluid's force cancelling between them as in a monolithic step;
the fluid keeps its own sequence of domains (A1's, ``FLUID_ETA``), so that
its kinetic energy is measured on the domains it was solved on.

It steps with one-step schemes only (:meth:`KinematicSplitting.scheme_problems`).  With one that
estimates its error (Crank–Nicolson) it takes adaptive steps (``[time] tolerance``,
:mod:`multilayer.coupling.clock`), under the paper's Robin term with its own error estimate
(:meth:`KinematicSplitting.estimate`);
the wall is factorized again when Δt changes, τ̃ of ``extrapolation = 2``
is extrapolated over the uneven steps.
"""

from __future__ import annotations

from collections.abc import Iterator

import attrs
import numpy as np
import scipy.sparse as sp

from multilayer.coupling.clock import Window, march, old_levels
from multilayer.coupling.contract import Coupler, StepReport
from multilayer.coupling.kit import (
    FLUID_ETA,
    coupled_case_problems,
    external_force,
    flow_rate_ends,
    fluid_columns,
    fluid_domain,
    fluid_groups,
    joint_report,
    lumen_layers,
    lumen_mass,
    quadratic,
    relative,
    thin_lumen_problems,
    window_loads,
)
from multilayer.coupling.structure import StructureStep, wall_energy
from multilayer.fluid.contract import Domain, Interface
from multilayer.numerics.newton import CHORD
from multilayer.numerics.stepsize import local_error
from multilayer.numerics.timescheme import TimeScheme, scheme_param
from multilayer.plugin.hookspecs import hookimpl
from multilayer.plugin.records import CouplerPlugin, Param
from multilayer.scene.state import State
from multilayer.wall.equilibrium import lumen_force
from multilayer.wall.stack import LUMEN

#: the Robin operator of the fluid step: the wall step's impedance on Γ, or the thin layer's inertia (the paper's)
ROBINS = ("impedance", "inertia")
#: why the splitting cannot take a fluid directly on a thick band
THICK_LUMEN = ("its steps hand over the thin layer's radial motion on Γ (and, with robin = 'inertia', its Robin term "
               "is that layer's mass ρ₁h/Δt, without which it loses its added-mass stability), while a band at the "
               "fluid moves in both components")
#: why the wall's impedance cannot take a nonlinear layer
NONLINEAR_IMPEDANCE = ("the fluid step's Robin term is the wall step's response condensed on Γ, and A3 completes "
                       "the wall's step by that response (one product with A⁻¹P), so that the wall moves with the "
                       "fluid, V̄_Γ = v̄, which closes the ledger and the lumen's volume; a nonlinear wall's "
                       "response depends on the load, and its step under the fluid's force would leave V̄_Γ ≠ v̄")
#: why the paper's Robin term cannot take a prescribed inflow
INERTIA_LEAK = ("its fluid step sees the wall as the thin layer's mass alone, so the fluid leaves through Γ faster "
                "than the wall moves, by (ω₁Δt)² with ω₁² = k/(ρ₁h) the wall's stiffness over that mass, and the "
                "prescribed inflow is lost through the wall (docs/theory.md, 'Volume')")


class KinematicSplitting(Coupler):
    name = "kinematic-splitting"
    loads = ("inlet", "outlet", "external")
    adaptive = True
    multistage = True

    def __init__(self, scheme: TimeScheme | str = "backward-euler", beta: float | None = None, extrapolation: int = 1,
                 robin: str = "impedance"):
        super().__init__(scheme)
        if robin not in ROBINS:
            raise ValueError(f"robin {robin!r} is not one of {', '.join(ROBINS)}")
        if beta is None:  # the impedance's A1 predicts the domain under the fluid's force; the paper's has none
            beta = 1.0 if robin == "impedance" else 0.0
        if not 0.0 <= beta <= 1.0:
            raise ValueError(f"beta must be in [0, 1], got {beta!r}")
        if extrapolation not in (1, 2):
            raise ValueError(f"extrapolation must be 1 or 2, got {extrapolation!r}")
        self.beta = float(beta)
        self.extrapolation = int(extrapolation)
        self.robin = robin

    def scheme_problems(self, scheme: TimeScheme) -> list[str]:
        """Under the paper's Robin term (``robin = "inertia"``) also one-step stages (two time levels): its structure
        step hands the thin layer's velocity to the fluid step as one level (A1's v*), and the step's identity is
        A1's and A2's over one level each.  Under the impedance A3 completes a whole wall step with the scheme's
        levels, so a multistep stage (BDF2's three levels) is stepped as the wall and the fluid step it alone."""
        problems = super().scheme_problems(scheme)
        if self.robin == "inertia":
            problems += [f"{scheme.name} has a stage of {stage.scheme.levels} time levels, and {self.name} with "
                         f"robin = 'inertia' takes one-step stages (two levels): its structure step hands the thin "
                         f"layer's velocity to the fluid step as one level"
                         for stage in scheme.stages if stage.scheme.levels != 2][:1]
        return problems

    def fluid_interface_block(self, case) -> bool:
        """The wall's impedance couples every two DOFs of Γ (the whole wall behind it condensed on the line)."""
        return self.robin == "impedance"

    def check_case(self, case) -> list[str]:
        problems = (super().check_case(case) + coupled_case_problems(self.name, case)
                    + thin_lumen_problems(self.name, case, THICK_LUMEN))
        if self.robin == "inertia":
            problems += [f"loads.{end} prescribes a flow rate, which {self.name} with robin = 'inertia' (the paper's "
                         f"scheme) does not conserve: {INERTIA_LEAK}; remove coupler.robin (the default "
                         "'impedance' conserves it), or choose 'monolithic'"
                         for end in flow_rate_ends(case)]
        else:
            problems += [f"{layer.path} ('{layer.model}') is nonlinear, which {self.name} with robin = 'impedance' "
                         f"cannot take: {NONLINEAR_IMPEDANCE}; set coupler.robin = 'inertia' (its structure step is "
                         "a whole wall step, solved by Newton's method), or choose 'monolithic' or "
                         "'dirichlet-neumann-implicit'"
                         for layer in case.layers if not layer.linear]
        return problems

    def initial_state(self, setup) -> State:
        """The setup's state at t = 0; with ``[initial] pressure`` the fluid's force on the thin layer at rest
        there as the last step's τ, so that a run started at equilibrium under constant loads stays there."""
        state = super().initial_state(setup)
        pressure = setup.case.initial.pressure
        if pressure is None:
            return state
        return attrs.evolve(state, extra={**state.extra, "traction": lumen_force(setup.wall, pressure, state.eta)})

    def energy(self, setup, state: State) -> dict[str, float]:
        return {**wall_energy(setup.stack, self.scheme, state, LUMEN),
                **setup.fluid.energy(state.fluid, fluid_domain(state)[0])}

    def traction(self, state: State, dt: float | None = None) -> np.ndarray:
        """τ̃: the fluid's force on the thin layer extrapolated from the last steps (0 at the start).

        τ of a step stands at its midpoint; with ``extrapolation`` = 2 and steps
        of changing length (``dt``: this step's, given for adaptive steps) the line
        through the last two is taken to this step's midpoint.
        """
        tau = state.extra.get("traction")
        if tau is None:
            return np.zeros_like(state.v)
        older = state.previous.extra.get("traction") if state.previous is not None else None
        if self.extrapolation == 2 and older is not None:
            if dt is None:
                return 2.0 * tau - older
            k1, k2 = state.t - state.previous.t, state.previous.t - state.previous.history(2)[1].t
            return tau + (dt + k1) / (k1 + k2) * (tau - older)
        return tau

    def evolve(self, setup, state: State) -> Iterator[tuple[State, StepReport]]:
        fluid, wall = setup.fluid, setup.wall
        adaptive = setup.case.time.adaptive
        structure = StructureStep(setup.stack, self.scheme, setup.dt, setup.stats("wall"), setup.case.solver,
                                  fluid_line=LUMEN, reuse=setup.case.reuse, chord=CHORD)
        P, R = wall.prolongations[LUMEN], wall.restrictions[LUMEN]
        masses = {i: lumen_mass(setup, i) for i in lumen_layers(setup)}
        # per Δt the Robin matrix, the same object every step (its slots are looked up once), and with the
        # impedance the wall's response to a load on Γ
        operators: dict[float, tuple] = {}

        def operator(wall: StructureStep, dt: float) -> tuple:
            key = wall.matrix_key(dt)  # the wall step's matrix: a new Δt, or a stage of another matrix, changes it
            if key not in operators:
                operators.clear()
                if self.robin == "inertia":
                    operators[key] = ((wall.scheme.inertia / dt) * lumen_mass(setup), None)
                else:
                    operators[key] = interface_impedance(wall, P, R, dt)
            return operators[key]

        def advance(state: State, w: Window) -> tuple[State, StepReport]:
            S, dt = w.scheme, w.dt
            a1 = structure.using(S)  # the step's (a stage's) scheme, the factors of the same matrix shared
            robin, response = operator(a1, dt)
            loads = window_loads(setup, S, w.t0, w.t1)
            tau = self.beta * self.traction(state, dt if adaptive else None)
            # A1: the structure, fluid frozen (its force only through β τ̃)
            forces = {"external": external_force(setup, loads["external"])}
            if self.beta:
                forces["splitting"] = P @ tau
            a = a1.step(state, forces, dt)
            eta_a1 = R @ a.wall.d
            # A2: the fluid on the domain A1 left, with the Robin term R(v̄ − V̄_Γ) from A1's test-level velocity
            # V̄_Γ: under the thin layer's inertia its new level (v̄ − β₁vⁿ)/β₀ then starts from vⁿ like the
            # fluid's trace, so u^{n+1} = v^{n+1} on Γ
            v_mean_a1 = R @ a.mean
            interface = Interface(robin, robin @ v_mean_a1 - tau)
            eta_old = fluid_domain(state)[0]  # where the fluid's last domain ended (the wall's ηⁿ but under the impedance)
            velocity = v_mean_a1 if response is None else (eta_a1 - eta_old) / dt
            domain = Domain(S.geometry([eta_a1, eta_old]), velocity)
            history = [x.fluid for x in state.history(S.old_levels)]
            system = fluid.system(history, domain, S, dt, (w.t0, w.t1), interface)
            sol = fluid.solve(system)
            v_new = fluid.wall_velocity(sol.state)
            v_bar = S.average([v_new, state.v])  # ū on Γ, the thin layer's test-level velocity
            traction = robin @ v_bar - interface.rhs  # the fluid's force on the wall over the step
            f = fluid.identity(system, sol, eta_old, eta_a1)
            extra = {"traction": traction}
            if response is None:
                wall_new = a.wall
                report = self.report(setup, S, state, a, f, masses, v_new, v_bar, tau, dt)
                if adaptive:
                    extra.update(self.estimate(state, w, a.wall.d, P, R, v_mean_a1 - v_bar))
            else:
                # A3: the wall's step again under the fluid's force: linear in it, one product with A⁻¹P
                forces = {"external": forces["external"], "fluid": P @ traction}
                wall_step = a1.finish(state.history(S.levels - 1), a.mean + response @ (traction - tau), forces, dt)
                wall_new = wall_step.wall
                report = self.impedance_report(wall_step, f)
                # the fluid's next step starts on the domain this one ended on, not on A3's wall: its kinetic
                # energy is measured on one sequence of domains (theory §6, "The fluid's own domains")
                extra[FLUID_ETA[0]] = eta_a1
            return state.then(S.old_levels, n=w.n + 1, t=w.t1, wall=wall_new, fluid=sol.state, v=v_new,
                              eta=R @ wall_new.d, extra=extra), report

        return march(setup, self.scheme, state, advance)

    @staticmethod
    def impedance_report(wall_step, f) -> StepReport:
        """The step's ledger under the impedance: the wall's identity (A3) and the fluid's (A2).

        The fluid's force does work Δt τ·V̄_Γ on the wall and Δt τ·v̄ on the
        fluid's side; V̄_Γ = v̄, so the two leave the ledger together, as in a
        monolithic step (what is left of them is the residual's).
        """
        return joint_report(wall_step, f, cancelled=("work.fluid",),
                            diagnostics={"energy.relative_residual.A2": relative(f["a2.residual"], f["a2.scale"])})

    @staticmethod
    def estimate(state: State, w: Window, d_new: np.ndarray, P, R, rate: np.ndarray) -> dict[str, np.ndarray]:
        """The splitting's own error estimate of the wall (theory §4, "The splitting's error"), as ``extra`` entries.

        ``rate`` = V̄_Γ − v̄: A1 moves the lumen at V̄_Γ, the fluid's trace moves at v̄.
        Z, their difference integrated (``splitting.Z``), is the splitting's defect in η;
        η − Z is the lumen as the fluid's trace integrates it.

        * ``estimate.wall.d``: the scheme's estimate of η − Z on the lumen line (rejects the step);
        * ``estimate.next.wall.d``: Δt times the rate averaged over this step and the last,
          the splitting's local error in η without the (−1)ⁿ part of the rate that the last
          steps leave and that no Δt of this step reduces (sets the next step only).
        """
        z_new = state.extra.get("splitting.Z", np.zeros_like(rate)) + w.dt * rate
        out = {"splitting.Z": z_new, "splitting.rate": rate}
        old = old_levels(state)
        if old is None:
            return out
        zs = [s.extra.get("splitting.Z", np.zeros_like(rate)) for s in old]
        k = [w.dt, old[0].t - old[1].t, old[1].t - old[2].t]
        out["estimate.wall.d"] = P @ local_error(R @ d_new - z_new, [R @ s.wall.d - z for s, z in zip(old, zs)], k,
                                                 w.scheme)
        out["estimate.next.wall.d"] = P @ (w.dt * 0.5 * (rate + state.extra.get("splitting.rate", rate)))
        return out

    def report(self, setup, S: TimeScheme, state: State, a, f, masses, v_new, v_bar, tau, dt: float) -> StepReport:
        """The step's ledger: A1's identity and A2's, the thin layer's inertia resolved on its own side.

        The thin layer's kinetic energy after A1 (velocity ``a.v``) is the one A2
        starts from; what testing its A2 inertia with v̄ leaves beyond the
        scheme's identity is ``dissipation.splitting`` (none when x̄ = x^{n+1}: β₀ = 1, backward Euler),
        the β force's net work ``dissipation.beta`` (theory §6).
        """
        v_star = a.v
        stored = {**a.stored}
        numerical_thin = splitting = 0.0
        for i, mass in masses.items():
            kinetic = quadratic(mass)
            stored[f"kinetic.layers[{i}]"] = S.stored(kinetic, [v_new, v_star])
            numerical_thin += S.numerical(kinetic, [v_new, v_star])
            splitting += S.alpha[0] * float((v_new - v_star) @ (mass @ (v_bar - S.average([v_new, v_star]))))
        stored_f, work_f, dissipation_f = fluid_groups(f, numerical=False)
        stored.update(stored_f)
        work = {**{k: w for k, w in a.work.items() if k != "work.splitting"}, **work_f}
        dissipation = {k: d for k, d in a.dissipation.items() if k != "dissipation.numerical.wall"}
        dissipation["dissipation.numerical.A1"] = a.dissipation["dissipation.numerical.wall"]
        dissipation["dissipation.numerical.A2"] = f["dissipation.numerical.fluid"] + numerical_thin
        dissipation.update(dissipation_f)
        if S.beta[0] != 1.0:  # x̄ = x^{n+1} (backward Euler): v̄ is A2's new level whatever A1's, no such term
            dissipation["dissipation.splitting"] = splitting
        if self.beta:  # the β force's net work: a term of the scheme, not work of a load
            dissipation["dissipation.beta"] = dt * float(tau @ v_bar) - a.work["work.splitting"]
        before = sum(wall_energy(setup.stack, S, state, LUMEN).values())  # A1's own identity, as a diagnostic
        after = sum(a.stored.values())
        a1_residual = after - before - sum(a.work.values()) + sum(a.dissipation.values())
        return StepReport(stored, work, dissipation, {
            "energy.relative_residual.A1": relative(a1_residual, max(abs(after), abs(before), 1e-300)),
            "energy.relative_residual.A2": relative(f["a2.residual"], f["a2.scale"]),
            **fluid_columns(f),
        })


def interface_impedance(step: StructureStep, P, R, dt: float) -> tuple[sp.csr_matrix, np.ndarray]:
    """(S_Γ, A⁻¹P): the wall step's impedance on the lumen line Γ and the step's response to a load there.

    A load τ on Γ (line numbering) changes the wall's V̄ by A⁻¹Pτ and its
    lumen velocity V̄_Γ by G τ, G = R A⁻¹ P (one back-substitution per line
    DOF, once per Δt).  S_Γ = G⁻¹ on the line DOFs the wall leaves free:
    the force the wall answers a change of V̄_Γ with, inertia, damping and
    stiffness of every layer behind Γ together (theory §6).
    """
    response = step.response(P, dt)
    G = R @ response
    free = np.flatnonzero(np.diag(G) > 0.0)
    impedance = np.zeros_like(G)
    impedance[np.ix_(free, free)] = np.linalg.inv(G[np.ix_(free, free)])
    return sp.csr_matrix(impedance), response


@hookimpl
def multilayer_couplers():
    return [CouplerPlugin(
        name="kinematic-splitting", factory=KinematicSplitting,
        params=(scheme_param(),
                Param("beta", "β", default=None, ge=0.0, le=1.0,
                      doc="share of the fluid's last force on the wall given to the structure step A1 "
                          "(default 1 under robin = 'impedance', where A1 predicts the fluid's domain; "
                          "0 under 'inertia', the paper's scheme)"),
                Param("extrapolation", type=int, default=1, choices=None, ge=1, le=2,
                      doc="order of the extrapolation of that force: 1 (last step) or 2 (linear)"),
                Param("robin", type=str, default="impedance", choices=ROBINS,
                      doc="the fluid step's Robin operator on Γ: 'impedance' (the default), the wall step's own "
                          "response condensed on Γ, with the wall's step then completed under the fluid's force "
                          "(v̄ = V̄_Γ: the lumen's volume follows the flow); 'inertia', the thin layer's mass "
                          "ρ₁h/Δt alone (the paper's scheme)")),
        doc="Kinematically coupled scheme: structure step, then fluid step with a Robin term (β, Crank–Nicolson).")]
