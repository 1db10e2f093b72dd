"""Properties of the readers of what people write: whatever the text, a protocol and a
measured-curve CSV are either read or refused with an InputError, never anything else;
YAML within the bounds reads exactly as ``yaml.safe_load`` reads it, but for numbers
(YAML 1.2's: tests/config/test_yaml_numbers.py)."""

import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import example, given, settings
from hypothesis import strategies as st

from labrig.config.bounded_yaml import load_with_nodes
from labrig.config.protocol import parse_protocol
from labrig.errors import InputError
from labrig.model.segments.measured import MAX_MAGNITUDE, read_csv_table

YAML_ALPHABET = st.sampled_from([*"abc01 :-[]{},&*!|>'\"\\#%@`.\n\t\x00", "é", "\ufeff"])


@settings(max_examples=300, deadline=None)
@given(st.text(YAML_ALPHABET, max_size=80))
@example("a: &x 1\nb: *x\na: 2\n")  # a duplicate key after an alias
@example("[" * 100)  # deeper than the bound, unclosed
@example("!!python/object:os.system ['ls']")  # a tag safe_load refuses
@example("name: .inf")
def test_any_text_is_a_protocol_or_one_input_error(text):
    try:
        parse_protocol(text, "p.yaml")
    except InputError as error:
        assert str(error).startswith("p.yaml:")


scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**6), 10**6),
    st.floats(allow_nan=False, width=32),
    # text that starts as no number can: where YAML 1.1 writes 1e5 or 089 as text,
    # YAML 1.2 reads a number, or the loader refuses the value
    st.text(st.characters(codec="utf-8", exclude_categories=("Cs", "Cc")), max_size=8).filter(
        lambda text: text[:1] not in set("+-.0123456789")
    ),
)
documents = st.recursive(
    scalars,
    lambda inner: (
        st.lists(inner, max_size=4)
        | st.dictionaries(st.text("abcxyz_", min_size=1, max_size=5), inner, max_size=4)
    ),
    max_leaves=30,
)


@settings(max_examples=200, deadline=None)
@given(documents, st.sampled_from([None, True, False]))
def test_within_the_bounds_yaml_reads_as_safe_load_reads_it(document, flow):
    text = yaml.safe_dump(document, default_flow_style=flow)
    data, _ = load_with_nodes(text)
    assert data == yaml.safe_load(text)


# pieces of rows: a body is any sequence of them
CSV_PIECES = st.sampled_from([*'0123456789.,-+eE \nnaif\r"', "1e308", "\ufeff", "\x00", "0,0,30\n"])
HEADER = "volume_ml,pressure_kpa,length_mm\n"


def read_csv_text(text: str) -> np.ndarray:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "curve.csv"
        path.write_text(text, encoding="utf-8")
        return read_csv_table(path)


@settings(max_examples=300, deadline=None)
@given(st.lists(CSV_PIECES, max_size=120).map("".join), st.booleans())
@example("0,0,30\n" * 10 + "1e308,1,30\n", True)
@example("0,0,30\n1,nan,31\n", True)
def test_any_text_is_a_curve_table_or_one_input_error(body, with_header):
    try:
        values = read_csv_text((HEADER if with_header else "") + body)
    except InputError as error:
        assert "\n" not in str(error)
        return
    assert values.shape[1] == 3 and len(values) >= 10
    assert np.all(np.isfinite(values)) and np.all(np.abs(values) <= MAX_MAGNITUDE)
    assert values[0, 0] >= 0 and np.all(np.diff(values[:, 0]) >= 0)


finite = st.floats(-1e5, 1e5, allow_nan=False)


@settings(max_examples=100, deadline=None)
@given(
    st.lists(st.floats(0.0, 10.0), min_size=10, max_size=40),
    st.lists(finite, min_size=40, max_size=40),
    st.lists(st.floats(1.0, 1e5), min_size=40, max_size=40),
)
def test_a_valid_table_reads_back_exactly(steps, pressures, lengths):
    volumes = np.cumsum([0.0, *steps[1:]])
    n = len(volumes)
    expected = np.column_stack([volumes, pressures[:n], lengths[:n]])
    rows = [",".join(repr(float(x)) for x in row) for row in expected]
    values = read_csv_text(HEADER + "\n".join(rows) + "\n")
    assert np.array_equal(values, expected)
    assert not any(math.isnan(x) for x in values.ravel())


@pytest.mark.parametrize("size", [1, 10])
def test_an_empty_body_names_the_rule(size):
    with pytest.raises(InputError, match="data rows; a curve needs at least 10"):
        read_csv_text(HEADER + "0,0,30\n" * (size - 1))
