"""The step experiments' protocol keys: prompts, reservoir steps, fluid, air reservoir
and blocked length, each bad input refused with the key and what is allowed."""

import textwrap

import pytest

from labrig.config.protocol import parse_protocol, plan
from labrig.errors import InputError


def protocol_text(specimen_extra: str = "", steps: str | None = None) -> str:
    steps = steps or textwrap.dedent(
        """\
          - infuse: {rate_ml_min: 20, volume_ml: 16}
          - prompt: {message: close the pump's valve, connect: reservoir}
          - reservoir: {volume_ml: 1.0, duration_s: 0.2}
          - hold: {seconds: 5}
        """
    )
    return (
        "name: step\n"
        f"specimen: {{segments: [B44-T30, B48-T26]{specimen_extra}}}\n"
        "limits: {max_pressure_kpa: 95, max_volume_ml: 17}\n"
        "steps:\n" + textwrap.indent(steps, "  ")
    )


def test_a_reservoir_step_protocol_is_valid_and_planned():
    protocol = parse_protocol(protocol_text(", fluid: air, air_reservoir_ml: 20"))
    assert protocol.specimen.fluid == "air"
    assert protocol.specimen.air_reservoir_ml == 20
    assert protocol.specimen.length == "free"
    p = plan(protocol)
    assert p.prompts == 1
    # 16 mL at 20 mL/min, the 0.2 s push and the 5 s hold; the prompt is open-ended
    assert p.duration_s == pytest.approx(48 + 0.2 + 5)
    assert p.max_volume_ml == pytest.approx(17)


@pytest.mark.parametrize(
    ("specimen", "steps", "message"),
    [
        (", air_reservoir_ml: 20", None, "air_reservoir_ml: 20 needs fluid: air"),
        (", fluid: oil", None, "specimen.fluid"),
        (", length: clamped", None, "specimen.length"),
        ("", "- reservoir: {volume_ml: 1}\n", "a reservoir step needs the reservoir connected"),
        (
            "",
            "- prompt: {message: open the reservoir, connect: reservoir}\n"
            "- infuse: {rate_ml_min: 20, volume_ml: 5}\n",
            "the pump is disconnected here",
        ),
        (
            "",
            "- prompt: {message: open it, connect: reservoir}\n- reservoir: {volume_ml: 6}\n",
            "steps[1].reservoir.volume_ml",
        ),
        ("", "- prompt: {message: ''}\n", "steps[0].prompt.message"),
        ("", "- prompt: {message: go, connect: syringe}\n", "steps[0].prompt.connect"),
        (
            "",
            "- infuse: {rate_ml_min: 20, volume_ml: 16.5}\n"
            "- prompt: {message: open it, connect: reservoir}\n"
            "- reservoir: {volume_ml: 1}\n",
            "brings the specimen to 17.5 mL, above limits.max_volume_ml",
        ),
    ],
)
def test_bad_step_experiments_name_the_key(specimen, steps, message):
    with pytest.raises(InputError) as error:
        parse_protocol(protocol_text(specimen, steps), "p.yaml")
    assert message in str(error.value)
    assert str(error.value).startswith("p.yaml: line ")


def test_a_prompt_can_reconnect_the_pump():
    steps = (
        "- prompt: {message: open the reservoir, connect: reservoir}\n"
        "- reservoir: {volume_ml: 1}\n"
        "- prompt: {message: open the pump's valve again, connect: pump}\n"
        "- infuse: {rate_ml_min: 20, volume_ml: 5}\n"
    )
    assert plan(parse_protocol(protocol_text("", steps))).max_volume_ml == pytest.approx(6)
