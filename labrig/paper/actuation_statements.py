"""Movie S7's three actuation times, on the simulated plumbing.

The paper inflates B44-T30 + B48-T26 to just below its first snap, decouples it from the
pump and pushes 1 mL from a small reservoir: with water the snap takes more than 1 s
(1.4 s), with air 0.3 s, with air and an extra air reservoir 0.1 s. Here the pair of the
library is inflated at 20 mL/min (water) or 40 mL/min (air) on
``labrig.sim.dynamic_plant`` until its segments hold 0.1 mL less than the model's first
snap, switched to the reservoir 3 s later, pushed 1 mL over 0.5 s 2 s after that (the
protocols' schedule, protocols/movie_s7*.yaml) and left for 15 s; the actuation time is
the 10-90 % time of the length at the camera's 60 frames a second
(``labrig.analysis.actuation``). The coupling's bore is the simulated rig's, 0.76 mm,
fitted on the water case with the calibrated library (docs/how-to/step-experiments.md):
the one constant fitted there.
"""

from __future__ import annotations

import numpy as np

from labrig.paper.actuator_statements import evidence
from labrig.paper.pair_scan import actuator_transitions
from labrig.paper.statements import MOVIE_S5, PREDICTION, Library, Outcome, within

# (key, fluid, air reservoir mL, pump mL/min, the paper's text, the tolerance in s)
CASES = (
    ("S7-water", "water", 0.0, 20.0, "more than 1 s (1.4 s)", (1.0, 2.8)),
    ("S7-air", "air", 0.0, 40.0, "0.3 s", (0.15, 0.6)),
    ("S7-air-reservoir", "air", 10.0, 40.0, "0.1 s", (0.05, 0.2)),
)
BELOW_SNAP_ML = 0.1
PUSH_ML, PUSH_S = 1.0, 0.5
CAMERA_FPS = 60.0
SETTLE_S = 15.0


def actuation_time_s(library: Library, names, fluid: str, reservoir_ml: float, rate_ml_min):
    """The length's 10-90 % time after the push (module docstring), or None where the
    pair has no snap on inflation."""
    from labrig.analysis.actuation import step_response
    from labrig.sim.dynamic_plant import FLUIDS, DynamicPlant, Plumbing

    snaps = evidence(actuator_transitions(library, names))
    if not snaps:
        return None
    target_ml = snaps[0].v_ml - BELOW_SNAP_ML
    rate = rate_ml_min / 60.0
    stop = [np.inf]

    def pump_ml(t: float) -> float:
        return rate * min(max(t, 0.0), stop[0])

    plant = DynamicPlant(
        [library(n) for n in names],
        pump_ml,
        plumbing=Plumbing(fluid=FLUIDS[fluid], air_reservoir_ml=reservoir_ml),
        fittings_length_mm=10.0,
    )
    t = 0.0
    while (short_ml := target_ml - plant.volumes_ml.sum()) > 0:  # air: the pump displaces more
        t += 0.05 if short_ml < 0.5 else 0.5
        plant.advance_to(t)
    stop[0] = t
    t_push = t + 5.0
    plant.connect("reservoir", t + 3.0)
    plant.push_reservoir(PUSH_ML, PUSH_S, t_push)
    t_end = t_push + SETTLE_S
    plant.advance_to(t_end)
    frames = np.arange(t_push - 1.0, t_end, 1.0 / CAMERA_FPS)
    lengths = np.array([plant.length_mm_at(f) for f in frames])
    return step_response(frames, lengths, t_push, t_end).actuation_time_s


def evaluate(library: Library, prefix: str) -> list[Outcome]:
    names = [prefix + n for n in MOVIE_S5]
    out = []
    for key, fluid, reservoir_ml, rate, paper, (low, high) in CASES:
        found = actuation_time_s(library, names, fluid, reservoir_ml, rate)
        holds = found is not None and within(found, low, high)
        text = "no snap to trigger" if found is None else f"{found:.2f} s"
        what = fluid + (f" + {reservoir_ml:g} mL air reservoir" if reservoir_ml else "")
        out.append(
            Outcome(
                key,
                f"Movie S7, (44,30)+(48,26) just below its snap, 1 mL pushed, {what}: "
                "actuation time",
                paper,
                text,
                bool(holds),
                PREDICTION,
                "" if holds else f"{text} (the length's 10-90 % time)",
                f"{low:g}-{high:g} s",
            )
        )
    return out
