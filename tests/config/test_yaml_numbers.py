"""A number means what it says: protocols and rig files read numbers as YAML 1.2 does,
and a plain value YAML 1.1 would read as another number (octal 045, base-60 1:30,
1_000, 0b101) is refused with its file, line and key, never read silently as 37 or 90."""

import math
import re
import textwrap

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from labrig.config.bounded_yaml import NumberError, load_with_nodes
from labrig.config.protocol import parse_protocol
from labrig.errors import InputError

PROTOCOL = textwrap.dedent(
    """\
    name: numbers
    specimen: {{segments: [B46-T20]}}
    limits:
      max_pressure_kpa: 95
      max_volume_ml: {value}
    steps:
      - infuse: {{rate_ml_min: 10, volume_ml: 0.5}}
    """
)


def read(value: str) -> float:
    return parse_protocol(PROTOCOL.format(value=value), "p.yaml").limits.max_volume_ml


def refusal(value: str) -> str:
    with pytest.raises(InputError) as error:
        read(value)
    message = str(error.value)
    assert "\n" not in message and "Traceback" not in message
    return message


@pytest.mark.parametrize(
    ("written", "message"),
    [
        ("045", "045 is 37 to YAML 1.1 and 45 to YAML 1.2: write 45 in decimal"),
        ("0100", "0100 is 64 to YAML 1.1 and 100 to YAML 1.2: write 100 in decimal"),
        ("010", "010 is 8 to YAML 1.1 and 10 to YAML 1.2: write 10 in decimal"),
        ("089", "089 is text to YAML 1.1 and 89 to YAML 1.2: write 89 in decimal"),
        ("1:30", "1:30 is 90 to YAML 1.1 and text to YAML 1.2: write 90 in decimal"),
        ("1:30.5", "1:30.5 is 90.5 to YAML 1.1 and text to YAML 1.2: write 90.5 in decimal"),
        ("1_000", "1_000 is 1000 to YAML 1.1 and text to YAML 1.2: write 1000 in decimal"),
        ("0b101", "0b101 is 5 to YAML 1.1 and text to YAML 1.2: write 5 in decimal"),
        ("-0x1F", "-0x1F is -31 to YAML 1.1 and text to YAML 1.2: write -31 in decimal"),
        ("0o45", "0o45 is octal 37 to YAML 1.2 and text to YAML 1.1: write 37 in decimal"),
    ],
)
def test_a_number_yaml_1_1_reads_otherwise_is_refused_with_its_line(written, message):
    assert (
        refusal(written) == f"p.yaml: line 5: limits.max_volume_ml: {message}, or quote it for text"
    )


@pytest.mark.parametrize(
    ("written", "value"),
    [("45", 45), ("45.0", 45.0), ("4.5e1", 45.0), ("1e1", 10.0), ("0x1F", 31), (".5", 0.5)],
)
def test_a_number_reads_as_written(written, value):
    assert read(written) == value


def test_quoted_it_is_text_and_a_number_field_says_so():
    assert refusal("'045'").endswith("limits.max_volume_ml: Input should be a valid number")


def test_a_label_of_digits_with_a_leading_zero_is_quoted():
    text = PROTOCOL.format(value=10).replace("[B46-T20]", "[089]")
    with pytest.raises(InputError, match=r"line 2: specimen.segments\[0\]: 089 is text to"):
        parse_protocol(text, "p.yaml")
    quoted = parse_protocol(text.replace("[089]", "['089']"), "p.yaml")
    assert quoted.specimen.segments == ["089"]


def test_an_integer_of_more_than_4300_digits_is_one_line():
    """Not Python's "Exceeds the limit (4300 digits) for integer string conversion"."""
    assert refusal("9" * 4301) == (
        "p.yaml: line 5: limits.max_volume_ml: a number of 4301 characters; numbers here "
        "have at most 100"
    )


def test_a_huge_integer_in_a_rig_file_is_one_line(tmp_path, capsys):
    from labrig.cli import main

    rig = tmp_path / "bench.yaml"
    rig.write_text(f"pump: {{port: /dev/ttyACM0, address: {'7' * 5000}}}\n")
    with pytest.raises(SystemExit) as exited:
        main(["rig", "check", str(rig)])
    _, err = capsys.readouterr()
    assert exited.value.code == 2
    assert err == (
        f"error: {rig}: line 1: pump.address: a number of 5000 characters; numbers here "
        "have at most 100\n"
    )


def test_an_explicit_tag_on_something_else_is_one_line():
    with pytest.raises(InputError, match=r"line 5: not valid YAML: '0b1' is no integer"):
        read("!!int 0b1")


# The pieces numbers are spelt with, in YAML 1.1 and 1.2 and by mistake
PIECES = st.sampled_from(
    [
        *"0123456789+-._:eE",
        *("00", "e-", "e+", "0x", "0o", "0b", "1F", "inf", ".inf", ".nan", "9" * 120),
    ]
)


def literal(text: str) -> float:
    """The value ``text`` says in decimal (Python's own parser of numbers)."""
    bare = text.lstrip("+-").lower()
    if bare in (".inf", ".nan"):
        return float(text.replace(".", ""))
    if bare.startswith("0x"):
        return int(text, 16)
    return float(text)


# spellings a YAML 1.1 reader gives another value than their decimal reading
YAML_1_1_ONLY = re.compile(r"[-+]?0[0-9_]+|.*[_:].*|[-+]?0[bo].*")


@settings(max_examples=400, deadline=None)
@given(st.lists(PIECES, min_size=1, max_size=6).map("".join))
@example("045")
@example("1:30")
@example("1e-300")
@example("1.0e+300")
@example(".nan")
@example("9" * 5000)
def test_a_number_is_refused_or_its_literal_value_never_another(text):
    """Any spelling: refused in one line naming the key, or read as what it says; a
    spelling YAML 1.1 reads as another number is never accepted."""
    try:
        data, _ = load_with_nodes(f"v: {text}\n")
    except NumberError as error:
        assert error.path == "v" and error.problem_mark.line == 0
        return
    except Exception as error:  # not a number at all: any other YAML error is fine
        assert type(error).__module__.startswith("yaml"), error
        return
    value = data["v"] if isinstance(data, dict) else None
    if isinstance(value, bool) or not isinstance(value, int | float):
        return  # text, null, true: the schema says "a valid number"
    assert not YAML_1_1_ONLY.fullmatch(text), f"{text!r} read as {value!r}"
    expected = literal(text)
    assert (math.isnan(value) and math.isnan(expected)) or value == expected
    # in a protocol it is that value, or a one-line refusal naming the key
    try:
        assert read(text) == expected
    except InputError as error:
        assert "limits.max_volume_ml" in str(error) and "\n" not in str(error)
