"""Pieces every coupler of a fluid and a wall shares: the interface mass, loads, ledger groups.

Couplers are plugins; what more than one of them needs lives here once.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import attrs
import numpy as np
import scipy.sparse as sp

from multilayer.coupling.contract import StepReport
from multilayer.fluid.contract import ENDS, Domain
from multilayer.numerics.timescheme import TimeScheme
from multilayer.plugin.records import Param
from multilayer.scene.setup import Setup
from multilayer.wall.stack import LUMEN

#: how a fluid couples to a first layer that is thick (``[coupler] lumen``): the values a coupler offers
LUMEN_CONDITIONS = ("no-slip", "radial")

#: the ``State.extra`` entries of the lumen's axial displacement and velocity under no-slip (line vectors)
AXIAL = ("eta_z", "v_z")


def lumen_param():
    """The ``lumen`` parameter of a coupler that takes a fluid directly on a thick band."""
    return Param("lumen", type=str, default="no-slip", choices=LUMEN_CONDITIONS,
                 doc="a thick first layer at the fluid: 'no-slip' (the default) glues both components, u = ∂_t d "
                     "on the lumen, and the fluid domain follows its axial motion too; 'radial' glues only its "
                     "radial motion, u = (0, ∂_t d_r) and d_z = 0 on the lumen (the seed's radial ALE map); "
                     "ignored under a thin first layer")


def coupled_case_problems(name: str, case) -> list[str]:
    """What a coupler of a fluid and a wall cannot run (no fluid, no wall, a prescribed wall)."""
    problems = []
    if case.fluid is None:
        problems.append(f"{name} couples a fluid to the wall: declare [fluid], or choose the coupler 'structure-only'")
    if not case.layers:
        problems.append(f"{name} needs a wall: declare [[layers]], or choose 'fluid-only'")
    if case.loads.wall_motion is not None:
        problems.append(f"loads.wall_motion prescribes the wall, which {name} computes: "
                        "remove it, or choose the coupler 'fluid-only' without [[layers]]")
    return problems


def flow_rate_ends(case) -> list[str]:
    """The open ends of ``case`` whose condition prescribes the flux (a flow rate), in :data:`ENDS` order."""
    return [end for end in ENDS if getattr(case.loads, end).constraint]


def thin_lumen_problems(name: str, case, why: str) -> list[str]:
    """The problem of a coupler that needs a thin layer at the fluid interface, with ``why``, when layers[0] is thick."""
    if not case.layers or case.layers[0].thin:
        return []
    return [(f"{name} needs a thin layer at the fluid interface, but layers[0] is '{case.layers[0].model}' "
             f"(thick): {why}; put a thin layer (e.g. 'koiter-shell' or 'wave-membrane') first in [[layers]], or "
             "choose 'monolithic' or 'dirichlet-neumann-implicit', which take a fluid directly on a thick band")]


class ThickLumen:
    """Mixin of a coupler that takes a fluid directly on a thick band (its ``lumen`` parameter).

    With ``lumen = "radial"`` the band's lumen line is glued radially: d_z = 0
    there (:meth:`radial_lines`), and the fluid's u_r on Γ is the band's
    radial velocity, as under a thin layer (theory §1).  With ``"no-slip"``
    both components are glued, u = ∂_t d on Γ, and the lumen's d_z and its
    velocity ride in ``State.extra`` (:data:`AXIAL`) to move the fluid
    domain axially (:func:`predicted_domain`).
    """

    def __init__(self, scheme: TimeScheme | str = "backward-euler", lumen: str = "no-slip"):
        super().__init__(scheme)
        if lumen not in LUMEN_CONDITIONS:
            raise ValueError(f"lumen {lumen!r} is not one of {', '.join(LUMEN_CONDITIONS)}")
        self.lumen = lumen

    def radial_lines(self, case) -> tuple[int, ...]:
        """The lumen line when layers[0] is thick (a thin first layer holds its d_z itself)."""
        return (LUMEN,) if thick_first(case) and self.lumen == "radial" else ()

    def no_slip(self, case) -> bool:
        """True when the fluid lies on a thick first layer under ``lumen = "no-slip"``."""
        return thick_first(case) and self.lumen == "no-slip"

    def initial_state(self, setup: Setup):
        """The setup's state at t = 0, with the lumen's d_z and its velocity under no-slip (``State.extra``)."""
        state = super().initial_state(setup)
        if not (setup.fluid is not None and self.no_slip(setup.case)):
            return state
        Rz = axial_restriction(setup)
        return attrs.evolve(state, extra={**state.extra, "eta_z": Rz @ state.wall.d, "v_z": Rz @ state.wall.V})


def thick_first(case) -> bool:
    """True when the case's first layer, at the fluid, is thick."""
    return bool(case.layers) and not case.layers[0].thin


def axial_restriction(setup: Setup) -> sp.csr_matrix:
    """Wall vector → the lumen line's d_z (line numbering)."""
    wall = setup.wall
    n = wall.lines[LUMEN].ndofs
    return sp.csr_matrix((np.ones(n), (np.arange(n), wall.line_z_dofs(LUMEN))), shape=(n, wall.ndofs))


def lumen_layers(setup: Setup) -> list[int]:
    """Indices of the thin layers on the fluid interface line (r = R)."""
    return [p.index for p in setup.wall.placements if p.line == LUMEN]


def lumen_mass(setup: Setup, index: int | None = None) -> sp.csr_matrix:
    """ρ₁h ∫ v ψ of the thin layers on the fluid interface (or of layer ``index``), in the line's numbering."""
    P = setup.wall.prolongations[LUMEN]
    masses = [setup.stack.matrices[i].mass for i in (lumen_layers(setup) if index is None else [index])]
    return (P.T @ sum(masses[1:], masses[0]) @ P).tocsr()


def window_loads(setup: Setup, scheme: TimeScheme, t0: float, t1: float) -> dict[str, float]:
    """The wall's pressure loads (``external``, ``interface``) averaged over the scheme's window of [t0, t1].

    The fluid's ends are the fluid's: it asks their conditions itself (:meth:`Fluid.system` takes the step's times).
    """
    a, b = scheme.load_window(t0, t1)
    loads = setup.case.loads
    return {key: getattr(loads, key).average(a, b) for key in ("external", "interface")}


def external_force(setup: Setup, pressure: float) -> np.ndarray:
    """The load vector of the external pressure P_e on the outer surface (wall numbering)."""
    return -pressure * setup.wall.line_load(setup.wall.outer_line)


def fluid_groups(terms: Mapping[str, float], numerical: bool = True) -> tuple[dict, dict, dict]:
    """The fluid's identity terms as ledger groups (stored, work, dissipation).

    Besides the fluid's own terms, whatever its ends' conditions report
    (``stored.*``, ``work.*``, ``dissipation.*`` columns) goes to its group:
    a coupler passes the ends through without knowing their kind.
    ``numerical=False`` leaves the fluid's numerical dissipation out, for a
    coupler that reports it together with another's.
    """
    stored = {"kinetic.fluid": terms["kinetic.fluid"], **{k: v for k, v in terms.items() if k.startswith("stored.")}}
    work = {k: terms[k] for k in ("work.inlet", "work.outlet", "work.wall") if k in terms}
    work.update({k: v for k, v in terms.items() if k.startswith("work.") and k not in work})
    own = ("dissipation.viscous.fluid", "dissipation.geometric.fluid", "dissipation.numerical.fluid")
    keys = own if numerical else own[:2]
    dissipation = {k: terms[k] for k in keys}
    dissipation.update({k: v for k, v in terms.items() if k.startswith("dissipation.") and k not in own})
    return stored, work, dissipation


def joint_report(wall_step, terms: Mapping[str, float], cancelled: Sequence[str] = (),
                 diagnostics: Mapping[str, float] | None = None) -> StepReport:
    """The ledger of a step whose wall moves with the fluid's trace: the wall's identity plus the fluid's.

    ``cancelled`` names the wall's work terms that are the fluid's own force, which the fluid's interface power
    cancels (left out of both); ``diagnostics`` are added to the fluid's columns.
    """
    stored_f, work_f, dissipation_f = fluid_groups(terms)
    work = {k: w for k, w in wall_step.work.items() if k not in cancelled}
    return StepReport({**wall_step.stored, **stored_f}, {**work, **work_f}, {**wall_step.dissipation, **dissipation_f},
                      {**(diagnostics or {}), **fluid_columns(terms)})


def fluid_columns(terms: Mapping[str, float]) -> dict[str, float]:
    """The fluid's columns that are neither energy nor work: each end's flux, mean pressure and state (``end.*``)."""
    return {k: v for k, v in terms.items() if k.startswith("end.")}


@attrs.frozen(eq=False)
class Prediction:
    """The explicit domain of a step whose wall is not known yet, and what it was predicted from.

    ``domain`` is what the fluid step is assembled on; ``velocity`` (and
    ``velocity_z`` under no-slip) the wall velocity predicted at tⁿ + θΔt
    (:func:`domain_velocity`), a partitioned coupler's first guess of the
    interface velocity.  ``levels`` holds, for a scheme whose fluid lives on
    its own domains (Crank–Nicolson, :func:`own_domains`), the fluid's η at
    tⁿ and tⁿ⁺¹ by :data:`FLUID_ETA` key: its kinetic energy is measured on
    them and the new one goes to the next state's ``extra``.
    """

    domain: Domain
    velocity: np.ndarray
    velocity_z: np.ndarray | None = None
    levels: Mapping[str, tuple[np.ndarray, np.ndarray]] = attrs.field(factory=dict)

    def identity_levels(self, state, eta_new: np.ndarray, axial: tuple | None) -> tuple:
        """(η at tⁿ, η at tⁿ⁺¹, the axial pair) the fluid's kinetic energy is measured on in the step's identity:
        the fluid's own levels where it has them, else the wall's (``state.eta``, ``eta_new``, ``axial``) — at
        tⁿ the fluid's own level where ``state`` has one, the domain its energy was measured on last (a stage
        after a Crank–Nicolson stage: :meth:`carried`)."""
        old, old_z = fluid_domain(state)
        eta = self.levels.get(FLUID_ETA[0], (old, eta_new))
        if axial is not None and FLUID_ETA[1] in state.extra:
            axial = (old_z, axial[1])
        return (*eta, self.levels.get(FLUID_ETA[1], axial))

    def extra(self) -> dict[str, np.ndarray]:
        """The fluid's new levels, for the next state's ``extra``."""
        return {key: new for key, (_, new) in self.levels.items()}

    def carried(self, extra: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The next state's ``extra`` from the old state's: the fluid's own new levels where this step has them,
        none where its fluid lives on the wall's levels, so that the next step measures the fluid where this one
        left it (the stages of TR-BDF2: a Crank–Nicolson stage on its own domains, a BDF2 stage on the wall's)."""
        return {**{k: v for k, v in extra.items() if k not in FLUID_ETA}, **self.extra()}


#: the ``State.extra`` entries of the fluid's own domain (monolithic and Dirichlet–Neumann under Crank–Nicolson, the
#: kinematic splitting under the wall's impedance): the lumen's η and, under no-slip, d_z
FLUID_ETA = ("fluid_eta", "fluid_eta_z")


def fluid_domain(state) -> tuple[np.ndarray, np.ndarray | None]:
    """(η, d_z) of the domain the fluid's kinetic energy is measured on in ``state``: its own where it has one."""
    eta_z = state.extra.get(AXIAL[0])
    return state.extra.get(FLUID_ETA[0], state.eta), state.extra.get(FLUID_ETA[1], eta_z)


def own_domains(scheme: TimeScheme) -> bool:
    """True when the fluid lives on its own sequence of domains: Crank–Nicolson, whose test level is the midpoint.

    A one-step scheme without numerical dissipation lets the geometric
    remainder G of an explicit domain (theory §5) grow; with its own levels
    G is the scheme's own ⅛ρ_f∫(J^{n+1} − Jⁿ)|u^{n+1} − uⁿ|² (theory §6).
    Backward Euler and BDF2 keep the wall's levels (their numbers unchanged).
    """
    return scheme.beta[0] != 1.0


def predicted_domain(scheme: TimeScheme, history: Sequence, dt: float) -> Prediction:
    """The explicit domain of a step whose wall is not known yet (monolithic, Dirichlet–Neumann).

    The wall velocity c is extrapolated to where the scheme evaluates its
    operator (:func:`domain_velocity`) and the displacement integrated from
    it, Σα_k η^{n+1−k} = Δt c.  Backward Euler and BDF2: the domain is the
    scheme's geometry of those, moving with c.  Crank–Nicolson
    (:func:`own_domains`): the fluid's domain runs from its own level η̃ⁿ
    (the prediction of the step before, ηⁿ at the start) to the prediction
    η̂^{n+1} = ηⁿ + Δt c: its geometry the midpoint (η̃ⁿ + η̂^{n+1})/2, its
    velocity (η̂^{n+1} − η̃ⁿ)/Δt (theory §6).  Under no-slip (``eta_z``,
    ``v_z`` in the states' ``extra``) the lumen's axial motion likewise.
    """
    components = [(lambda x: x.eta, lambda x: x.v, FLUID_ETA[0])]
    if AXIAL[0] in history[0].extra:
        components.append((lambda x: x.extra[AXIAL[0]], lambda x: x.extra[AXIAL[1]], FLUID_ETA[1]))
    own = own_domains(scheme)
    parts, levels = [], {}
    for displacement, velocity, key in components:
        etas = [displacement(x) for x in history]
        c = domain_velocity(scheme, history, dt, displacement, velocity)
        new = scheme.displacement(c, etas, dt)
        if own:
            old = history[0].extra.get(key, etas[0])
            levels[key] = (old, new)
            parts.append((c, scheme.geometry([new, old]), (new - old) / dt))
        else:
            parts.append((c, scheme.geometry([new, *etas]), c))
    (c, eta, moving), *axial = parts
    if not axial:
        return Prediction(Domain(eta, moving), c, None, levels)
    c_z, eta_z, moving_z = axial[0]
    return Prediction(Domain(eta, moving, eta_z, moving_z), c, c_z, levels)


def domain_velocity(scheme: TimeScheme, history: Sequence, dt: float, displacement, velocity) -> np.ndarray:
    """The wall velocity at tⁿ + θΔt, extrapolated from the velocities the wall's displacement moved with.

    Those are the scheme's test-level velocities v̄ of the previous steps
    (Σα_j η^{k+1−j} = Δt_k v̄_k).  Where the test level is the new level
    (backward Euler, BDF2) they are the velocity levels, extrapolated as
    the scheme does (:meth:`TimeScheme.extrapolate`).  Crank–Nicolson's test
    level is the midpoint: its velocity levels carry the scheme's undamped
    mode (−1)ⁿ, which v̄ = (vᵏ⁺¹ + vᵏ)/2 cancels and the displacement never
    sees; extrapolating the levels would double that mode into the domain's
    motion (theory §6).  So the samples are the displacement's difference
    quotients (η^{k+1} − ηᵏ)/Δt_k at the midpoints of the steps in the
    states' chain (the initial level v⁰ at t⁰ where the chain starts),
    extrapolated linearly to tⁿ + Δt/2: second order.

    ``displacement`` and ``velocity`` read η and v from a state (radial or
    axial component).
    """
    if not own_domains(scheme):
        return scheme.extrapolate([velocity(x) for x in history])
    samples = []  # (time, velocity) newest first, at most two
    state = history[0]
    while len(samples) < 2:
        older = state.previous
        if older is None:  # the chain's end: the initial level (or a chain cut short) is a sample of its own
            samples.append((state.t, velocity(state)))
            break
        samples.append((0.5 * (state.t + older.t), (displacement(state) - displacement(older)) / (state.t - older.t)))
        state = older
    if len(samples) == 1:
        return samples[0][1]
    (ta, ca), (tb, cb) = samples
    target = history[0].t + scheme.theta * dt
    return ca + (target - ta) / (ta - tb) * (ca - cb)


def quadratic(M: sp.spmatrix):
    """x ↦ ½ xᵀ M x."""
    return lambda x: 0.5 * float(x @ (M @ x))


def relative(residual: float, scale: float) -> float:
    """|residual| / scale, 0 for a zero scale."""
    return abs(residual) / scale if scale > 0 else 0.0
