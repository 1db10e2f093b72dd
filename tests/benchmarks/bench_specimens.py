"""Benchmark: the run's interlocks on specimens that are not their model, healthy and
faulty, on the whole simulated rig. Prints the figures docs/reference/interlocks.md
quotes and the table of docs/performance.md.

Run: python tests/benchmarks/bench_specimens.py [--write-docs]

Every case is one ``labrig run`` of a protocol on the simulated rig (the real drivers,
the runner and its interlocks; virtual time) whose rig file's ``sim.specimen`` gives the
truth. The healthy matrix: partial cycles (30 mL in, 18 out, 18 in), the truth 0.5 and
2 times as stiff as the protocol's model, another library's curves than the calibrated
one the protocol names, a measured CSV that ends before its peak as the model,
hysteresis, a first cycle stiffer than the rest (the Mullins effect), air trapped in
the water line (4 and 10 mL), rates from 0.1 to 60 mL/min, and a segment whose model
is a label no library holds. Each must complete: a trip is a false trip. The faulty
matrix: the sensor's output wire cut before the run (at the zeroing) and during it (at
5 and 20 mL), with and without the pull-up, a burst at 5, 15 and 28 mL, and leaks of
2-20 % of the flow: the volume the pump had supplied at the fault and when it stopped.

The margins behind the thresholds, from each healthy run's file: the deepest fall of
the pressure's 0.1 s means below the infusion's peak so far (a burst trips below
``BURST_FLOOR_FRACTION`` of it, so the healthy deepest must stay above), and, where the
specimen is filled again to the most it held, the pressure there against the first
time (a leak trips below 1 - ``LEAK_DROP_FRACTION``). Syringe backlash is not in the
matrix: the pump emulator has none.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from labrig.cli.performance_doc import add_write_docs_argument, markdown_table, script_doc
from labrig.config.protocol import load_protocol
from labrig.config.rig_file import PressureConfig, PumpConfig, RigConfig, SimConfig, SimSpecimen
from labrig.model.segments.catalog import load_segment
from labrig.recording.run_reader import open_run, read_log
from labrig.rig.assembly import build_rig
from labrig.run import interlocks
from labrig.run.runner import Runner

DEMO = ["B48-T30", "B50-T20"]
SI = ["si:B48-T30", "si:B50-T20"]
EMPTIED = (30.0, 30.0, 0.0)  # in, and all of it out
# A refill's judgement, measured and not used: back within 0.5 mL of the most held,
# after 1 mL infused again, the pressure against the first time there.
REFILL_NEAR_ML = 0.5
SLOW = {"rate": 1.0, "cycle": (6.0, 3.6, 3.6), "rate_hz": 200.0}  # 1 mL/min, 200 S/s
SLOW_EMPTIED = {**SLOW, "cycle": (6.0, 6.0, 0.0)}
FIRST_1_2 = {"first_cycle_factor": 1.2}
REFILL_AFTER_ML = 1.0


def protocol_text(
    segments: list[str], rate: float, cycle=(30.0, 18.0, 18.0), rate_hz: float = 1000.0
) -> str:
    """A partial cycle: ``cycle`` = (in, out, in again) mL at ``rate`` mL/min."""
    first, out, again = cycle
    return (
        "name: specimen matrix\n"
        f"specimen: {{segments: [{', '.join(segments)}], fittings_length_mm: 10}}\n"
        "rig: sim\n"
        "limits: {max_pressure_kpa: 100, max_volume_ml: 45}\n"
        f"acquisition: {{pressure_rate_hz: {rate_hz:g}, camera_fps: 0}}\n"
        "analysis: {compare_model: false}\n"
        "steps:\n"
        "  - zero_pressure: {duration_s: 1}\n"
        f"  - infuse: {{rate_ml_min: {rate:g}, volume_ml: {first:g}}}\n"
        f"  - withdraw: {{rate_ml_min: {rate:g}, volume_ml: {out:g}}}\n"
        + (f"  - infuse: {{rate_ml_min: {rate:g}, volume_ml: {again:g}}}\n" if again else "")
    )


@dataclass
class Case:
    name: str
    model: list[str]  # the protocol's segments
    truth: dict = field(default_factory=dict)  # sim.specimen
    rate: float = 40.0
    cycle: tuple = (30.0, 18.0, 18.0)
    rate_hz: float = 1000.0
    cut_at_ml: float | None = None  # the sensor's output wire cut (0: at the zeroing)
    pull_up_kohm: float | None = 4.7
    fault_ml: float | None = None  # where a burst or a leak's fault is

    @property
    def healthy(self) -> bool:
        faults = ("burst_at_ml", "leak_fraction")
        return self.cut_at_ml is None and not any(k in self.truth for k in faults)


def cases(work: Path) -> list[Case]:
    # a measured table of B48-T30 that ends at 5 mL, before its peak: the model
    csv = work / "lab-b48-t30-to-5ml.csv"
    curve = load_segment("B48-T30")
    rows = curve.v_ml <= 5.0
    table = np.column_stack([curve.v_ml[rows], curve.p_kpa[rows], curve.l_mm[rows]])
    np.savetxt(csv, table, delimiter=",", header="volume_ml,pressure_kpa,length_mm", comments="")
    short = (20.0, 12.0, 12.0)
    return [
        Case("the model itself", DEMO),
        Case("0.5 x as stiff", DEMO, {"stiffness_factor": 0.5}),
        Case("2 x as stiff", SI, {"stiffness_factor": 2.0}),
        Case("paper: curves", DEMO, {"segments": ["paper:B48-T30", "paper:B50-T20"]}, cycle=short),
        Case("si: curves", DEMO, {"segments": SI}),
        Case("paper-r: curves", DEMO, {"segments": ["paper-r:B48-T30", "paper-r:B50-T20"]}),
        Case("CSV model ending at 5 mL", [str(csv), "B50-T20"], {"segments": DEMO}),
        Case("hysteresis 5 kPa", DEMO, {"hysteresis_kpa": 5.0}),
        Case("first cycle 1.3 x", SI, {"first_cycle_factor": 1.3}),
        Case("hysteresis 3 kPa, first cycle 1.2 x", SI, {"hysteresis_kpa": 3.0, **FIRST_1_2}),
        Case("air 4 mL", DEMO, {"air_ml": 4.0}),
        Case("air 10 mL", DEMO, {"air_ml": 10.0}),
        Case("0.1 mL/min", DEMO, rate=0.1, cycle=(1.0, 0.6, 0.6), rate_hz=20.0),
        Case("1 mL/min", DEMO, **SLOW),
        Case("10 mL/min", DEMO, rate=10.0),
        Case("60 mL/min", DEMO, rate=60.0),
        Case("no model (a label)", ["LAB-S37"], {"segments": ["B46-T20", "B46-T22"]}),
        Case("healthy, emptied", DEMO, cycle=EMPTIED),
        Case("air 10 mL, emptied", DEMO, {"air_ml": 10.0}, cycle=EMPTIED, rate=60.0),
        # faulty
        Case("wire cut at the zeroing", DEMO, cut_at_ml=0.0, fault_ml=0.0),
        Case("wire cut at 5 mL", DEMO, cut_at_ml=5.0, fault_ml=5.0),
        Case("wire cut at 20 mL", DEMO, cut_at_ml=20.0, fault_ml=20.0),
        Case("wire cut at 5 mL, no pull-up", DEMO, cut_at_ml=5.0, pull_up_kohm=None, fault_ml=5.0),
        Case("burst at 5 mL", DEMO, {"burst_at_ml": 5.0}, fault_ml=5.0),
        Case("burst at 15 mL", DEMO, {"burst_at_ml": 15.0}, fault_ml=15.0),
        Case("burst at 28 mL", DEMO, {"burst_at_ml": 28.0}, fault_ml=28.0),
        Case("burst at 15 mL, 60 mL/min", DEMO, {"burst_at_ml": 15.0}, rate=60.0, fault_ml=15.0),
        Case(
            "burst at 15 mL, air 10 mL", DEMO, {"burst_at_ml": 15.0, "air_ml": 10.0}, fault_ml=15.0
        ),
        Case("burst at 3 mL, 1 mL/min", DEMO, {"burst_at_ml": 3.0}, **SLOW, fault_ml=3.0),
        *(
            Case(f"leak {share:.0%}, emptied", DEMO, {"leak_fraction": share}, cycle=EMPTIED)
            for share in (0.02, 0.05, 0.1, 0.2)
        ),
        Case("leak 6 %, 1 mL/min, emptied", DEMO, {"leak_fraction": 0.06}, **SLOW_EMPTIED),
        Case("leak 20 %, partial cycles", DEMO, {"leak_fraction": 0.2}),
    ]


@dataclass
class Outcome:
    status: str
    reason: str
    stopped_ml: float
    fault_supplied_ml: float | None
    wall_s: float
    deepest_fall: float  # the lowest 0.1 s mean over the infusion's peak so far
    refill_ratio: float  # the pressure back near the most held, over the first time
    lowest_withdrawing_kpa: float  # the lowest sample withdrawing with volume counted


def run_case(case: Case, work: Path) -> Outcome:
    path = work / "protocol.yaml"
    path.write_text(protocol_text(case.model, case.rate, case.cycle, case.rate_hz))
    loaded = load_protocol(path)
    config = RigConfig(
        pump=PumpConfig(port="emulator"),
        pressure=PressureConfig(pull_up_kohm=case.pull_up_kohm),
        sim=SimConfig(specimen=SimSpecimen(**case.truth) if case.truth else None),
    )
    wall0 = time.monotonic()
    rig = build_rig(loaded.protocol, config)
    emulator = rig.simulation.emulator
    cut_s = []

    def cut() -> None:
        rig.clock.wait_for(lambda: rig.simulation.daq_tasks, 60.0)
        if case.cut_at_ml:
            at_ml = case.cut_at_ml
            rig.clock.wait_for(lambda: emulator.net_volume_ml(rig.clock.now()) >= at_ml, 1e5)
        else:
            rig.clock.sleep(0.2)  # inside the zeroing
        cut_s.append(rig.clock.now())
        rig.simulation.daq_tasks[-1].fail("vout-floating")

    out = work / "run.h5"
    with rig.clock.participate():
        if case.cut_at_ml is not None:
            rig.clock.start_thread(cut, "cut")
        result = Runner(loaded, rig, out).run()
    end_s = rig.clock.now()
    stopped_ml = emulator.net_volume_ml(end_s + 30.0)
    fault_ml = emulator.net_volume_ml(cut_s[0]) if cut_s else case.fault_ml
    found = margins(out)
    out.unlink()
    return Outcome(
        result.status, result.reason, stopped_ml, fault_ml, time.monotonic() - wall0, *found
    )


def margins(path: Path) -> tuple[float, float, float]:
    """(deepest fall, refill ratio, lowest withdrawing) of a run's file, judged as the
    interlock judges: the lowest sample while the pump withdraws with more than
    ``LEAK_COUNTED_ML`` counted."""
    with open_run(path) as run:
        pressure = read_log(run, 1, "pressure")
        pump = read_log(run, 1, "pump")
    t, p = pressure.time_s, pressure.fields["value"]
    if len(t) == 0:
        return float("nan"), float("nan"), float("nan")
    bins = np.floor(t / interlocks.SPECIMEN_BIN_S).astype(int)
    edges = np.flatnonzero(np.diff(bins)) + 1
    starts = np.concatenate([[0], edges])
    means = np.add.reduceat(p, starts) / np.diff(np.concatenate([starts, [len(p)]]))
    bin_t = bins[starts] * interlocks.SPECIMEN_BIN_S
    state, volume, pump_t = pump.fields["state"], pump.fields["value"], pump.time_s
    infusing = state == b"infusing"
    deepest, refill = 1.0, float("nan")
    first_v, first_p, most = [0.0], [0.0], 0.0
    # each run of infusing statuses is one infusion
    runs = np.split(np.arange(len(state)), np.flatnonzero(np.diff(infusing.astype(int))) + 1)
    for index in runs:
        if not infusing[index[0]] or len(index) < 2:
            continue
        t0, t1 = pump_t[index[0]], pump_t[index[-1]]
        inside = (bin_t >= t0) & (bin_t + interlocks.SPECIMEN_BIN_S <= t1)
        m = means[inside]
        if len(m):
            peak = np.maximum.accumulate(m)
            armed = peak >= interlocks.BURST_ARMED_KPA
            if armed.any():
                deepest = min(deepest, float(np.min(m[armed] / peak[armed])))
        v_at = np.interp(bin_t[inside], pump_t[index], volume[index])
        start_v = v_at[0] if len(v_at) else 0.0
        for v, pm in zip(v_at, m, strict=True):
            if v > most:
                first_v.append(v)
                first_p.append(pm)
                most = v
            elif (
                np.isnan(refill)
                and start_v < most - REFILL_AFTER_ML
                and v >= max(most - REFILL_NEAR_ML, start_v + REFILL_AFTER_ML)
            ):
                refill = float(pm / np.interp(v, first_v, first_p))
    withdrawing = state == b"withdrawing"
    counted = np.interp(t, pump_t, volume)
    at = np.interp(t, pump_t, withdrawing.astype(float)) > 0.5
    judged = at & (counted > interlocks.LEAK_COUNTED_ML)
    lowest = float(np.min(p[judged])) if judged.any() else float("nan")
    return deepest, refill, lowest


# what a reason begins with, and the outcome it is in the table
OUTCOMES = (
    ("zeroing", "refused at the zeroing"),
    ("pressure sensor wire open", "wire open"),
    ("the specimen lost pressure", "lost pressure"),
    ("the specimen leaks", "leak"),
    ("pressure reading frozen", "frozen"),
    ("pressure reading", "out of the sensor's range"),
    ("pressure ", "pressure limit"),
)


def figure(healthy: bool, value: float) -> str:
    return "" if not healthy or np.isnan(value) else f"{value:.2f}"


def outcome_of(reason: str) -> str:
    return next((label for start, label in OUTCOMES if reason.startswith(start)), reason)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_write_docs_argument(parser)
    args = parser.parse_args()
    doc = script_doc(["specimens"], args.write_docs)
    rows = []
    wall0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="labrig-specimens-") as tmp:
        work = Path(tmp)
        for case in cases(work):
            outcome = run_case(case, work)
            healthy = case.healthy
            tripped = outcome.status != "complete"
            if healthy:
                verdict = "FALSE TRIP" if tripped else "completed"
                detected = ""
            else:
                verdict = outcome_of(outcome.reason) if tripped else "NOT CAUGHT"
                fault = outcome.fault_supplied_ml
                detected = (
                    f"{outcome.stopped_ml:.2f} ({outcome.stopped_ml - fault:+.2f})"
                    if tripped and fault
                    else f"{outcome.stopped_ml:.2f}"
                )
            truth = ", ".join(f"{k} {v}" for k, v in case.truth.items()) or "the model"
            row = (
                "healthy" if healthy else "fault",
                case.name,
                truth,
                f"{case.rate:g}",
                verdict,
                detected,
                f"{outcome.deepest_fall:.2f}" if healthy else "",
                ""
                if not healthy or np.isnan(outcome.refill_ratio)
                else f"{outcome.refill_ratio:.2f}",
                ""
                if not healthy or np.isnan(outcome.lowest_withdrawing_kpa)
                else f"{outcome.lowest_withdrawing_kpa:.2f}",
                f"{outcome.wall_s:.1f} s",
            )
            rows.append(row)
            print(" | ".join(str(c) for c in row), "|", outcome.reason[:150], flush=True)
    healthy_rows = [r for r in rows if r[0] == "healthy"]
    false_trips = sum(r[4] != "completed" for r in healthy_rows)
    table = markdown_table(
        (
            "",
            "case",
            "truth (sim.specimen)",
            "mL/min",
            "outcome",
            "pump stopped at mL (after the fault)",
            "deepest fall",
            "refill ratio",
            "lowest withdrawing (kPa)",
            "wall",
        ),
        rows,
    )
    summary = (
        f"False trips: {false_trips} of {len(healthy_rows)} healthy runs. Deepest fall: the "
        "lowest 0.1 s mean over the infusion's peak so far (a burst trips below "
        f"{interlocks.BURST_FLOOR_FRACTION:g}). Refill ratio: the pressure back within "
        f"{REFILL_NEAR_ML:g} mL of the most held, over the first time there (not judged: "
        "it strays both ways without a leak). Lowest withdrawing: the lowest sample while "
        f"withdrawing with more than {interlocks.LEAK_COUNTED_ML:g} mL counted (a leak "
        f"trips below -{interlocks.LEAK_SUCTION_KPA:g}). All {len(rows)} runs: "
        f"{time.monotonic() - wall0:.0f} s wall."
    )
    print(summary)
    doc.publish("specimens", f"{table}\n\n{summary}")


if __name__ == "__main__":
    main()
