"""The dry run: what a protocol will do on a rig, and whether it can, before anything moves.

``labrig run`` prints it before every run and refuses to start on a problem;
``labrig run --dry-run`` stops after it. It checks what needs the rig as well as the
protocol (the syringe's rate range and capacity) and predicts, from the stability
model, the peak pressure the specimen will reach against the pressure limit (a
specimen with no model, ``specimen.model: none``, gets none and says so).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from labrig.config.protocol import InfuseStep, Protocol, WithdrawStep, iter_plan, plan
from labrig.config.rig_file import RigConfig
from labrig.drivers.phd_ultra_protocol import force_limit_pressure_kpa, rate_limits_ml_min


@dataclass
class DryRunReport:
    lines: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.problems

    @property
    def text(self) -> str:
        out = list(self.lines)
        out += [f"warning: {w}" for w in self.warnings]
        out += [f"error: {p}" for p in self.problems]
        return "\n".join(out)


def dry_run_report(protocol: Protocol, rig: RigConfig) -> DryRunReport:
    report = DryRunReport()
    summary = plan(protocol)
    syringe = rig.pump.syringe
    where = "simulated rig" if rig.sim is not None else f"pump on {rig.pump.port}"
    report.lines += [
        f"protocol {protocol.name!r} on the {where}",
        f"  specimen    {' + '.join(protocol.specimen.segments)}"
        + ("" if protocol.specimen.has_model else " (labels: no model)"),
        f"  duration    {summary.duration_s / 60:.1f} min ({summary.repetitions} repetitions)",
        f"  volume      {summary.infused_ml:g} mL infused, {summary.withdrawn_ml:g} mL "
        f"withdrawn, at most {summary.max_volume_ml:g} mL in the specimen "
        f"(limit {protocol.limits.max_volume_ml:g} mL)",
    ]
    report.lines.append(
        "  pump        infuse only (pump.infuse_only)"
        if rig.pump.infuse_only
        else "  pump        infuses and withdraws"
    )
    _backstop(protocol, rig, report)
    low, high = rate_limits_ml_min(syringe.diameter_mm)
    for location, step, _ in iter_plan(protocol.steps):
        if isinstance(step, InfuseStep | WithdrawStep):
            kind = "infuse" if isinstance(step, InfuseStep) else "withdraw"
            if kind == "withdraw" and rig.pump.infuse_only:
                report.problems.append(
                    f"{location}.withdraw: the rig's pump is infuse-only (pump.infuse_only)"
                )
            rate = step.infuse.rate_ml_min if kind == "infuse" else step.withdraw.rate_ml_min
            if not low <= rate <= high:
                report.problems.append(
                    f"{location}.{kind}.rate_ml_min = {rate:g}: a {syringe.diameter_mm:g} mm "
                    f"syringe on a PHD ULTRA runs at {low:.3g} to {high:.4g} mL/min"
                )
    _aggregate_rate(protocol, rig, report)
    if summary.max_volume_ml > syringe.volume_ml:
        report.problems.append(
            f"the specimen needs {summary.max_volume_ml:g} mL but the syringe holds "
            f"{syringe.volume_ml:g} mL"
        )
    _predict_pressure(protocol, summary.max_volume_ml, report)
    return report


# The USB-6009 samples its analog inputs in turn, at most this many samples a second
# over all of them.
DAQ_AGGREGATE_RATE_HZ = 48_000.0


def _aggregate_rate(protocol: Protocol, rig: RigConfig, report: DryRunReport) -> None:
    """The pressure rate on every input the DAQ reads (the sensor's supply, a load
    cell), within what the USB-6009 samples in total: else the run faults at start."""
    inputs = ["the sensor"]
    if rig.pressure.supply_channel is not None:
        inputs.append("its supply (pressure.supply_channel)")
    if protocol.specimen.length == "blocked":
        inputs.append("the load cell (specimen.length: blocked)")
    rate_hz = protocol.acquisition.pressure_rate_hz
    if rate_hz * len(inputs) > DAQ_AGGREGATE_RATE_HZ:
        report.problems.append(
            f"acquisition.pressure_rate_hz = {rate_hz:g} on {len(inputs)} inputs "
            f"({', '.join(inputs)}) is {rate_hz * len(inputs):g} S/s; the USB-6009 samples "
            f"at most {DAQ_AGGREGATE_RATE_HZ:g} S/s in total: at most "
            f"{DAQ_AGGREGATE_RATE_HZ / len(inputs):g} Hz"
        )


# A backstop above this many times the pressure limit protects nothing the specimen
# would notice; below about 1.5 times it, the plunger's friction and the tubing's
# resistance could stall a healthy run.
BACKSTOP_WARN_FACTOR = 2.0
BACKSTOP_SUGGEST_FACTOR = 1.5


def _backstop(protocol: Protocol, rig: RigConfig, report: DryRunReport) -> None:
    """The pump's force limit as the pressure it stalls at: what holds the pressure if
    labrig itself has crashed and the pump runs on to its step target."""
    pump = rig.pump
    diameter_mm = pump.syringe.diameter_mm
    area_mm2 = math.pi / 4 * diameter_mm**2
    stall_kpa = force_limit_pressure_kpa(pump.force_limit_pct, pump.rated_force_n, diameter_mm)
    limit_kpa = protocol.limits.max_pressure_kpa
    report.lines.append(
        f"  backstop    force limit {pump.force_limit_pct} % of {pump.rated_force_n:.1f} N on "
        f"the {diameter_mm:g} mm syringe ({area_mm2:.1f} mm²): the pump stalls above "
        f"{stall_kpa:.1f} kPa (pressure limit {limit_kpa:g} kPa)"
    )
    if rig.sim is None and stall_kpa > BACKSTOP_WARN_FACTOR * limit_kpa:
        at_100_kpa = force_limit_pressure_kpa(100, pump.rated_force_n, diameter_mm)
        suggested = min(100, math.ceil(100 * BACKSTOP_SUGGEST_FACTOR * limit_kpa / at_100_kpa))
        report.warnings.append(
            f"after a crash the pump pushes to {stall_kpa:.0f} kPa, "
            f"{stall_kpa / limit_kpa:.1f}x the pressure limit: pump.force_limit_pct: "
            f"{suggested} stalls it at {suggested / 100 * at_100_kpa:.0f} kPa"
        )


def _predict_pressure(protocol: Protocol, volume_ml: float, report: DryRunReport) -> None:
    """The model's peak pressure up to the largest volume, against the limit; for a
    specimen with no model, that there is none (and any label that looks like a
    model's name misspelt)."""
    from labrig.config.segment_names import label_warnings, unknown_segment_hint
    from labrig.errors import InputError
    from labrig.model.actuator.prediction import predicted_peak_pressure_kpa
    from labrig.model.segments.catalog import load_segment

    specimen, limit = protocol.specimen, protocol.limits.max_pressure_kpa
    if not specimen.has_model:
        report.lines.append(
            f"  pressure    no model peak: the specimen has no model (specimen.model: none); "
            f"the pressure limit {limit:g} kPa and the interlocks guard the run"
        )
        report.warnings += label_warnings(specimen.segments)
        return
    segments = []
    for index, spec in enumerate(specimen.segments):
        try:
            segments.append(load_segment(spec))
        except InputError as exc:
            problem = f"specimen.segments[{index}]: {exc}"
            if str(exc).startswith(f"unknown segment {spec!r}"):
                problem += f"; {unknown_segment_hint(spec)}"
            report.problems.append(problem)
    if len(segments) < len(specimen.segments):
        return
    peak_kpa, at_ml = predicted_peak_pressure_kpa(segments, volume_ml)
    report.lines.append(
        f"  pressure    model peak {peak_kpa:.1f} kPa at {at_ml:.2f} mL (limit {limit:g} kPa)"
    )
    if peak_kpa >= limit:
        report.warnings.append(
            f"the model predicts {peak_kpa:.1f} kPa at {at_ml:.2f} mL, at or above the "
            f"pressure limit {limit:g} kPa: the run will stop there"
        )
    if len(segments) == 1:
        _warn_before_valley(segments[0], volume_ml, report)


# how far the pressure must rise again past the valley for the run's curve to show it
RISE_PAST_VALLEY_KPA = 1.0


def _warn_before_valley(segment, volume_ml: float, report: DryRunReport) -> None:
    """A single-segment run that stops before its segment's valley (and the rise after
    it) cannot become a measured segment: ``labrig library add`` refuses a curve that
    still falls at its end."""
    valley = segment.valley
    if valley is None:
        return
    rise = float(segment.pressure_kpa(volume_ml)) - valley.p_kpa
    if volume_ml <= valley.v_ml or rise < RISE_PAST_VALLEY_KPA:
        report.warnings.append(
            f"the run stops at {volume_ml:g} mL, before {segment.name}'s valley at "
            f"{valley.v_ml:.2f} mL and the rise after it (model): labrig library add "
            "cannot use it; infuse past the valley, until the curve stiffens again"
        )
