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
    from labrig.config.rig_file import RigConfig
    from labrig.config.yaml_schema import parse_yaml_model
    from labrig.errors import InputError
    from labrig.rig.check import check_rig, report

    if rig_file is None and not sim:
        raise InputError("rig check: give a rig file (RIG.yaml) or --sim")
    bench = None
    if rig_file is not None:
        try:
            text = rig_file.read_text(encoding="utf-8")
        except OSError as exc:
            raise InputError(f"{rig_file}: cannot read the rig file ({exc.strerror})") from None
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
