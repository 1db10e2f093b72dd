"""``labrig protocol``: check a protocol file, or print the schema for editors."""

from __future__ import annotations

import click


@click.group()
def protocol() -> None:
    """Validate protocol files and print their JSON Schema."""


@protocol.command()
@click.argument("file", type=click.Path(dir_okay=False, path_type=str))
def validate(file: str) -> None:
    """Check FILE against the protocol schema; print a summary or what is wrong, and
    warn of segment names that name nothing, or labels that look like a model's names
    misspelt (``specimen.model: none``)."""
    from labrig.config.protocol import load_protocol, plan
    from labrig.config.segment_names import name_warnings

    loaded = load_protocol(file)
    specimen = loaded.protocol.specimen
    summary = plan(loaded.protocol)
    click.echo(
        f"{file}: valid protocol {loaded.protocol.name!r}: {summary.repetitions} repetitions, "
        f"{summary.duration_s / 60:.1f} min, {summary.infused_ml:g} mL infused, "
        f"at most {summary.max_volume_ml:g} mL in the specimen"
        + ("" if specimen.has_model else "; no model (specimen.model: none)")
    )
    for warning in name_warnings(specimen):
        click.echo(f"warning: {warning}", err=True)


@protocol.command()
def schema() -> None:
    """Print the protocol format as JSON Schema (for YAML language servers)."""
    from labrig.config.protocol import protocol_json_schema

    click.echo(protocol_json_schema())
