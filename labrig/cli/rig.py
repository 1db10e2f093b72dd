"""``labrig rig``: the rig itself, before any protocol (``rig check``: the pre-flight)."""

from __future__ import annotations

from pathlib import Path

import click


@click.group()
def rig() -> None:
    """The rig's devices."""


@rig.command()
@click.argument("rig_file", required=False, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--sim", is_flag=True, help="Check the simulated rig (with RIG_FILE: its wiring).")
@click.option(
    "--fault",
    type=click.Choice(
        ["no-reply", "wrong-address", "daq-missing", "marker-hidden", "sensor-offset"]
    ),
    help="Simulated rig only: inject one fault, to see what the check says.",
)
def check(rig_file: Path | None, sim: bool, fault: str | None) -> None:
    """Connect to every device of RIG_FILE (or of the simulated rig) and read it;
    nothing moves. Exit 0 when every device passes, 2 otherwise."""
    from labrig.config.rig_file import RigConfig, read_rig_text
    from labrig.config.yaml_schema import parse_yaml_model
    from labrig.errors import InputError
    from labrig.rig.check import check_rig, report

    if rig_file is None and not sim:
        raise InputError("rig check: give a rig file (RIG.yaml) or --sim")
    bench = None
    if rig_file is not None:
        text = read_rig_text(rig_file)
        bench = parse_yaml_model(text, str(rig_file), RigConfig, what="a rig configuration")
    simulated = sim or (bench is not None and bench.sim is not None)
    if fault is not None and not simulated:
        raise InputError("--fault applies to the simulated rig only (use --sim)")
    if simulated:
        from labrig.rig.check_sim import check_sim_rig, simulated_config

        checks = check_sim_rig(simulated_config(bench), fault)
    else:
        checks = check_rig(bench)
    text, code = report(checks)
    click.echo(text)
    if code:
        raise click.exceptions.Exit(code)


@rig.command()
@click.option("--sim", is_flag=True, help="On the simulated rig (the only one a soak may kill).")
@click.option("--runs", type=click.IntRange(min=1), default=200, show_default=True)
@click.option("--seed", type=click.IntRange(min=0), default=1, show_default=True)
@click.option("--json", "as_json", is_flag=True, help="One JSON object: summary and runs.")
def soak(sim: bool, runs: int, seed: int, as_json: bool) -> None:
    """RUNS simulated runs, each with one device fault at a random rig time; checks the
    pump stopped within 1 s of the fault, the file finalised with the reason, no sample
    before the fault lost, memory flat. One summary line; exit 0 only if all were safe."""
    import json
    import logging

    from labrig.errors import InputError
    from labrig.rig.soak import soak as run_soak
    from labrig.rig.soak import verdict_dict

    if not sim:
        raise InputError(
            "rig soak: it kills devices, so it runs on the simulated rig only: add --sim"
        )

    def report(verdict) -> None:
        if not verdict.safe and not as_json:
            click.echo(
                f"run {verdict.run} ({verdict.fault}): UNSAFE: {'; '.join(verdict.problems)}"
            )

    # every run breaks a device on purpose: the drivers' warnings about it are expected
    logging.getLogger("labrig").setLevel(logging.ERROR)
    summary, verdicts = run_soak(runs, seed, on_run=report)
    if as_json:
        payload = {
            "summary": {**summary.__dict__, "ok": summary.ok, "line": summary.line()},
            "runs": [verdict_dict(v) for v in verdicts],
        }
        click.echo(json.dumps(payload))
    else:
        click.echo(summary.line())
    if not summary.ok:
        raise click.exceptions.Exit(1)
