"""The simulated specimen with its plumbing's dynamics: the step experiments' plant.

``labrig.sim.plant.Plant`` is the quasi-static rig's specimen (incompressible water,
overdamped exchange between segments). This one adds what decides how fast a snap
happens when the specimen is hit by a quick step (the paper's actuation-time movie) and
what holds the actuator's ends (the blocked-force test):

- each segment hangs off an inlet manifold through a coupling with viscous resistance
  R (Poiseuille), an entrance/exit loss K rho Q|Q| / (2 A^2) and an inertance rho l / A
  (``Coupling.through``: a bore and a length, the fluid's viscosity and density);
- the fluid is compressible: water with its bulk modulus, air as a polytropic gas
  (index 1 isothermal, 1.4 adiabatic), so every volume is a compliance V / (n P_abs);
  the manifold holds the lines' dead volume, an optional rigid air reservoir, the
  syringe's air while the pump is connected, and air trapped in a water line;
- the latex wall is viscoelastic: the membrane's pressure is p(v) plus a damping
  eta_wall(v) dv/dt (a Kelvin-Voigt wall whose viscosity follows from the latex's loss
  tangent, thinning as the wall stretches): with air the flow resistance is 55 times
  smaller than with water, and the wall is what keeps a snap from being instantaneous;
- the inlet is connected either to the pump (its displacement) or, after a technician
  prompt, to a small reservoir pushed in over a short time;
- with the length blocked, the segments' axial stiffness (the latex wall in tension,
  E A / l0) carries the reaction force F = (sum l_i(v_i) + fittings - L_blocked) /
  sum(1/k_i) that a load cell reads, and each membrane feels p_i(v_i) + F dl_i/dv_i
  (the derivative of the energy with the length constraint, as in
  ``labrig.model.blocked``).

The state (segment volumes, coupling flows, manifold pressure, and the gas pressure in
each segment when the fluid is compressible enough to matter) is integrated with
scipy's LSODA (it switches to a stiff method where the water's compliance, 10^6 times
below a segment's, or the air's fast ringing calls for one) on the virtual clock,
lazily, up to the latest time anyone asks about, between the breakpoints of the inputs
(connections, pushes). In the slow limit it follows the model's quasi-static path
(tested). Thread-safe.
"""

from __future__ import annotations

import bisect
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from labrig.model.blocked import axial_stiffness_n_per_mm
from labrig.model.segments.curve import SegmentCurve
from labrig.sim.plant import ScalarCurve
from labrig.sim.specimen import SpecimenBehaviour

ATMOSPHERE_KPA = 101.325
# kPa s/mL per Pa s/m^3 (and kPa s^2/mL per Pa s^2/m^3): 1e-3 kPa/Pa times 1e-6 m^3/mL
SI_TO_ML = 1e-9
# The latex of the paper's tubes: wall thickness over radius.
LATEX_H_OVER_R = 0.79 / 6.35
# Natural-rubber latex dissipates about a tenth of the stored energy per radian at 1 Hz
# (loss tangent 0.1): a wall viscosity G''/omega = 0.1 * 490 kPa / (2 pi s^-1).
LATEX_VISCOSITY_KPA_S = 0.1 * 490.0 / (2 * np.pi)
# The integrator's tolerances (relative, absolute: mL, mL/s, kPa)
RTOL, ATOL = 1e-6, 1e-7


@dataclass(frozen=True)
class Fluid:
    """A working fluid: viscosity (Pa s), density at atmospheric pressure (kg/m^3),
    and either a bulk modulus (kPa, a liquid) or a polytropic index (a gas)."""

    name: str
    viscosity_pa_s: float
    density_kg_m3: float
    bulk_modulus_kpa: float | None = None
    polytropic_index: float = 1.0

    @property
    def is_gas(self) -> bool:
        return self.bulk_modulus_kpa is None

    def density_at(self, p_kpa: float) -> float:
        """Density at gauge pressure ``p_kpa`` (a gas's grows with it)."""
        if not self.is_gas:
            return self.density_kg_m3
        return self.density_kg_m3 * (ATMOSPHERE_KPA + p_kpa) / ATMOSPHERE_KPA

    def compliance_ml_per_kpa(self, volume_ml: float, p_kpa: float) -> float:
        """dV/dp of a volume of this fluid: V/K, or V/(n P_abs) for a gas."""
        if self.is_gas:
            return volume_ml / (self.polytropic_index * (ATMOSPHERE_KPA + p_kpa))
        return volume_ml / self.bulk_modulus_kpa


WATER = Fluid("water", 1.0e-3, 998.0, bulk_modulus_kpa=2.2e6)
# Isothermal: the fill takes a minute, and in a snap the gas compliance matters little
# beside the wall (a polytropic index up to 1.4 changes the S7 times by under 5 %).
AIR = Fluid("air", 1.81e-5, 1.204, polytropic_index=1.0)
FLUIDS = {"water": WATER, "air": AIR}


@dataclass(frozen=True)
class Coupling:
    """The connection of one segment to the manifold: linear resistance (kPa s/mL),
    quadratic loss (kPa s^2/mL^2, at the given density) and inertance (kPa s^2/mL)."""

    resistance_kpa_s_per_ml: float
    loss_kpa_s2_per_ml2: float
    inertance_kpa_s2_per_ml: float

    @classmethod
    def through(
        cls,
        fluid: Fluid,
        bore_mm: float,
        length_mm: float,
        *,
        loss_coefficient: float = 1.5,
        p_kpa: float = 0.0,
    ) -> Coupling:
        """A round bore: Poiseuille 128 mu l/(pi d^4), a sharp entrance and exit
        (K = 0.5 + 1.0) and rho l / A, for ``fluid`` at gauge pressure ``p_kpa``."""
        d, length = bore_mm * 1e-3, length_mm * 1e-3
        area = np.pi * d * d / 4
        rho = fluid.density_at(p_kpa)
        return cls(
            resistance_kpa_s_per_ml=128 * fluid.viscosity_pa_s * length / (np.pi * d**4) * SI_TO_ML,
            # rho Q^2 / (2 A^2): Pa for Q in m^3/s; Q in mL/s is 1e-6 m^3/s, Pa is 1e-3 kPa
            loss_kpa_s2_per_ml2=loss_coefficient * rho / (2 * area * area) * 1e-15,
            inertance_kpa_s2_per_ml=rho * length / area * SI_TO_ML,
        )


def wall_damping_kpa_s_per_ml(v0_ml: float, w_ml: float) -> float:
    """eta_wall of a latex tube holding V0 + w: the hoop viscous stress 3 eta eps_dot
    times h/r, with eps_dot = w_dot/(2V) and h/r = (H/R)/lambda^2, lambda^2 = V/V0:
    1.5 eta (H/R) V0 / V^2."""
    volume = v0_ml + max(w_ml, -0.9 * v0_ml)
    return 1.5 * LATEX_VISCOSITY_KPA_S * LATEX_H_OVER_R * v0_ml / (volume * volume)


@dataclass(frozen=True)
class Plumbing:
    """What surrounds the specimen: the fluid, the couplings, the manifold's dead
    volume, an air reservoir, the lines' wall compliance and the syringe's volume (its
    air is in the system while the pump is connected)."""

    fluid: Fluid = WATER
    bore_mm: float = 0.76
    coupling_length_mm: float = 20.0
    dead_volume_ml: float = 2.0
    air_reservoir_ml: float = 0.0
    line_compliance_ml_per_kpa: float = 0.002
    syringe_ml: float = 50.0
    # air trapped in a water line (mL at atmospheric pressure): a gas compliance on the
    # manifold whatever the working fluid
    trapped_air_ml: float = 0.0


class DynamicPlant:
    """The specimen and its plumbing as functions of the pump's volume history and of
    the technician's actions (``connect``, ``push_reservoir``)."""

    def __init__(
        self,
        segments: Sequence[SegmentCurve],
        volume_ml_at: Callable[[float], float],
        *,
        plumbing: Plumbing = Plumbing(),
        coupling: Coupling | None = None,
        t0_s: float = 0.0,
        fittings_length_mm: float = 0.0,
        blocked: bool = False,
        wall_damping: bool = True,
        history_s: float = 600.0,
        sample_s: float = 1e-3,
        method: str = "LSODA",
        behaviour: SpecimenBehaviour | None = None,
    ) -> None:
        if not segments:
            raise ValueError("a plant needs at least one segment")
        self.segments = tuple(segments)
        self.volume_ml_at = volume_ml_at
        self.plumbing = plumbing
        self.fluid = plumbing.fluid
        self.coupling = coupling or Coupling.through(
            self.fluid, plumbing.bore_mm, plumbing.coupling_length_mm
        )
        self.fittings_length_mm = float(fittings_length_mm)
        self.blocked = blocked
        self.wall_damping = wall_damping
        self.history_s = float(history_s)
        self.sample_s = float(sample_s)
        self.method = method
        self.behaviour = behaviour
        self._lock = threading.RLock()
        self._curves = [ScalarCurve(curve) for curve in self.segments]
        self._v0 = [float(curve.V0_ml) for curve in self.segments]
        # the segments' axial compliances in series (mm/N)
        self._compliance_mm_per_n = sum(1.0 / axial_stiffness_n_per_mm(c) for c in self.segments)
        n = len(self.segments)
        # the segments' gas pressures are states only where a segment's own compliance
        # matters; water's is 10^6 times below a membrane's and is left out
        self._gas = self.fluid.is_gas
        self._n_states = 2 * n + 1 + (n if self._gas else 0)
        self._t = float(t0_s)
        self._y = np.zeros(self._n_states)
        self._l_blocked_mm = self._free_length(self._y[:n])
        self._connected = "pump"
        self._pushes: list[tuple[float, float, float]] = []  # (t0, duration, volume)
        self._breakpoints: list[float] = []
        self._history_t: list[float] = [self._t]
        self._history: list[np.ndarray] = list(self._outputs_of(self._y[:, None]))

    # --- inputs --------------------------------------------------------------------
    @property
    def n(self) -> int:
        return len(self.segments)

    @property
    def connected(self) -> str:
        return self._connected

    def connect(self, target: str, t_s: float) -> None:
        """From ``t_s`` the inlet is on ``target`` ("pump" or "reservoir")."""
        if target not in ("pump", "reservoir"):
            raise ValueError(f"connect to pump or reservoir, not {target!r}")
        with self._lock:
            self.advance_to(t_s)
            self._connected = target
            self._breakpoints.append(t_s)
            self._breakpoints.sort()

    def push_reservoir(self, volume_ml: float, duration_s: float, t_s: float) -> None:
        """Push ``volume_ml`` from the reservoir in evenly over ``duration_s`` from ``t_s``."""
        if self._connected != "reservoir":
            raise RuntimeError("the reservoir is not connected: connect it first")
        with self._lock:
            self.advance_to(t_s)
            self._pushes.append((t_s, duration_s, volume_ml))
            self._breakpoints.extend((t_s, t_s + duration_s))
            self._breakpoints.sort()

    def _reservoir_ml(self, t: float) -> float:
        return sum(v * min(max((t - t0) / d, 0.0), 1.0) for t0, d, v in self._pushes)

    def _supply(self, t: float) -> tuple[float, float]:
        """(displacement rate into the manifold in mL/s, the manifold's volume in mL)."""
        p = self.plumbing
        volume = p.dead_volume_ml + p.air_reservoir_ml
        if self._connected == "pump":
            h = 1e-4
            rate = (self.volume_ml_at(t) - self.volume_ml_at(t - h)) / h
            if self._gas:
                volume += p.syringe_ml - self.volume_ml_at(t)
            return rate, volume
        rate = sum(v / d for t0, d, v in self._pushes if t0 <= t < t0 + d)
        if self._gas:
            volume += sum(v for _, _, v in self._pushes) - self._reservoir_ml(t)
        return rate, volume

    # --- the equations ---------------------------------------------------------------
    def _free_length(self, w) -> float:
        return sum(c.length(wi) for c, wi in zip(self._curves, w, strict=True)) + (
            self.fittings_length_mm
        )

    def force_n(self, w) -> float:
        """The load cell's reading (N, compression positive) at segment volumes ``w``."""
        if not self.blocked:
            return 0.0
        return (self._free_length(w) - self._l_blocked_mm) / self._compliance_mm_per_n

    def _membranes(self, w) -> list[float]:
        """Each membrane's elastic pressure at ``w``, with the length constraint's
        F dl/dv when blocked."""
        force = self.force_n(w)
        pressures = []
        for curve, wi in zip(self._curves, w, strict=True):
            p, _ = curve.pressure_and_slope(wi)
            if self.blocked:
                p += force * curve.length_slope(wi)
            pressures.append(p)
        return pressures

    def _rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        n, c = self.n, self.coupling
        w, q, p_m = y[:n], y[n : 2 * n], y[2 * n]
        supply, manifold_ml = self._supply(t)
        membranes = self._membranes(w)
        rho_ratio = self.fluid.density_at(p_m) / self.fluid.density_kg_m3
        loss = c.loss_kpa_s2_per_ml2 * rho_ratio
        inertance = c.inertance_kpa_s2_per_ml * rho_ratio
        dy = np.empty_like(y)
        for i in range(n):
            eta = wall_damping_kpa_s_per_ml(self._v0[i], w[i]) if self.wall_damping else 0.0
            if self._gas:
                p_i = y[2 * n + 1 + i]
                dw = (p_i - membranes[i]) / eta if eta > 0 else q[i]
                volume = self._v0[i] + w[i]
                dy[2 * n + 1 + i] = (q[i] - dw) / self.fluid.compliance_ml_per_kpa(volume, p_i)
            else:
                dw = q[i]
                p_i = membranes[i] + eta * q[i]
            dy[i] = dw
            # |Q| smoothed below 0.01 mL/s: the kink of Q|Q| at rest stalls the
            # solver's Newton iterations; the loss there is negligible either way
            drop = c.resistance_kpa_s_per_ml * q[i] + loss * q[i] * np.hypot(q[i], 0.01)
            dy[n + i] = (p_m - p_i - drop) / inertance
        compliance = self.plumbing.line_compliance_ml_per_kpa
        compliance += self.fluid.compliance_ml_per_kpa(manifold_ml, p_m)
        if self.plumbing.trapped_air_ml > 0:
            # isothermal: the bubble holds V0 P_atm / P_abs at gauge pressure p_m
            absolute_kpa = max(ATMOSPHERE_KPA + p_m, 1.0)
            bubble_ml = self.plumbing.trapped_air_ml * ATMOSPHERE_KPA / absolute_kpa
            compliance += AIR.compliance_ml_per_kpa(bubble_ml, p_m)
        dy[2 * n] = (supply - float(np.sum(q))) / compliance
        return dy

    def _outputs_of(self, states: np.ndarray) -> np.ndarray:
        """Rows of (sensor pressure, length, force, segment volumes...) of the states
        (columns of ``states``), with the segment curves evaluated on whole arrays."""
        n = self.n
        w = states[:n]
        free = self.fittings_length_mm + sum(
            s.length_mm(wi) for s, wi in zip(self.segments, w, strict=True)
        )
        force = (
            (free - self._l_blocked_mm) / self._compliance_mm_per_n if self.blocked else 0 * free
        )
        length = np.full_like(free, self._l_blocked_mm) if self.blocked else free
        return np.vstack([states[2 * n], length, force, w]).T

    # --- integration -----------------------------------------------------------------
    def advance_to(self, t_s: float) -> None:
        """Integrate up to ``t_s`` (no-op for a time already passed)."""
        with self._lock:
            while self._t < t_s - 1e-12:
                i = bisect.bisect_right(self._breakpoints, self._t + 1e-12)
                end = t_s
                if i < len(self._breakpoints):
                    end = min(end, self._breakpoints[i])
                self._integrate(end)

    def _integrate(self, end_s: float) -> None:
        start = self._t
        n_samples = max(1, int(np.ceil((end_s - start) / self.sample_s)))
        times = np.linspace(start, end_s, n_samples + 1)[1:]
        if self._at_rest(start, end_s):
            states = np.repeat(self._y[:, None], len(times), axis=1)
            end_state = self._y
        else:
            solution = solve_ivp(
                self._rhs,
                (start, end_s),
                self._y,
                method=self.method,
                rtol=RTOL,
                atol=ATOL,
                dense_output=True,
            )
            if not solution.success:
                raise RuntimeError(
                    f"the plant's integration failed at {start:.4f} s: {solution.message}"
                )
            states, end_state = solution.sol(times), solution.y[:, -1].copy()
        outputs = self._outputs_of(states)
        if self.behaviour is not None and self._connected == "pump":
            for row, t in zip(outputs, times.tolist(), strict=True):
                row[0] = self.behaviour.pressure_kpa(t, self.volume_ml_at(t), row[0])
        self._history_t.extend(times.tolist())
        self._history.extend(outputs)
        self._t, self._y = end_s, end_state
        if self._t - self._history_t[0] > 1.5 * self.history_s:
            cut = bisect.bisect_left(self._history_t, self._t - self.history_s)
            del self._history_t[:cut], self._history[:cut]

    def _at_rest(self, start_s: float, end_s: float) -> bool:
        """Whether the state stands still from ``start_s`` to ``end_s`` within the
        integrator's own tolerance: nothing is supplied then (the inputs change only at
        breakpoints and pump commands, so a supply equal at both ends and not flowing at
        either is none in between) and every component's rate, times the interval, is
        below what the integrator may be off by (rtol |y| + atol). An integration over
        the same interval would then move each component by less than that: a prompt
        at rest costs no restarts of the stiff integrator."""
        if self._supplied_ml(start_s) != self._supplied_ml(end_s):
            return False
        if self._supply(start_s)[0] != 0.0 or self._supply(end_s)[0] != 0.0:
            return False
        rates = np.abs(self._rhs(start_s, self._y))
        return bool(np.all(rates * (end_s - start_s) <= RTOL * np.abs(self._y) + ATOL))

    def _supplied_ml(self, t: float) -> float:
        """What the inlet's source has delivered by ``t`` (mL)."""
        if self._connected == "pump":
            return float(self.volume_ml_at(t))
        return self._reservoir_ml(t)

    # --- queries -------------------------------------------------------------------
    @property
    def volumes_ml(self) -> np.ndarray:
        """Current volume of each segment, from its unpressurised state."""
        with self._lock:
            return self._y[: self.n].copy()

    def series_at(self, t_s, column: int):
        """Column ``column`` of the outputs (0 pressure, 1 length, 2 force, 3+ volumes)
        at the given times, advancing as needed; one float for one float."""
        t = np.asarray(t_s, dtype=float)
        with self._lock:
            if t.size == 0:
                return np.empty_like(t)
            self.advance_to(float(t.max()))
            history_t = self._history_t
            if float(t.min()) < history_t[0] - 1e-9:
                raise ValueError(
                    f"plant history starts at {history_t[0]:.3f} s; asked for {t.min():.3f} s"
                )
            first = max(bisect.bisect_right(history_t, float(t.min())) - 1, 0)
            last = min(bisect.bisect_left(history_t, float(t.max())) + 1, len(history_t))
            values = [row[column] for row in self._history[first:last]]
            result = np.interp(t, history_t[first:last], values)
        return float(result) if isinstance(t_s, float) else result

    def pressure_kpa_at(self, t_s):
        """Manifold (sensor) pressure."""
        return self.series_at(t_s, 0)

    def length_mm_at(self, t_s):
        """Distance between the markers (constant when blocked)."""
        return self.series_at(t_s, 1)

    def force_n_at(self, t_s):
        """The load cell's force (N, compression positive; zero when free)."""
        return self.series_at(t_s, 2)

    def segment_volumes_ml_at(self, t_s) -> np.ndarray:
        """Each segment's volume at the given times (rows: times)."""
        return np.stack([self.series_at(t_s, 3 + i) for i in range(self.n)], axis=-1)
