"""Reading a measured-curve CSV: no cell of the file is ever shown in an error, and a
table of millions of rows is read by a fast parser (the same numbers as numpy's)."""

import numpy as np
import pytest

from labrig.errors import InputError
from labrig.model.segments import measured
from labrig.model.segments.measured import read_csv_table

HEADER = "volume_ml,pressure_kpa,length_mm"


@pytest.mark.parametrize(
    ("cell", "expected"),
    [
        ("SECRET-TOKEN-abc", "not a number (a decimal number such as 12.5 or 1.25e1)"),
        ("inf", "not a finite number (inf and nan are not allowed)"),
    ],
)
def test_a_bad_cell_is_named_by_its_place_never_shown(tmp_path, cell, expected):
    path = tmp_path / "bad.csv"
    rows = [f"{0.1 * i:.1f},{i},20" for i in range(8)]
    rows[3] = f"0.3,{cell},20"
    path.write_text(HEADER + "\n" + "\n".join(rows) + "\n")
    with pytest.raises(InputError) as error:
        read_csv_table(path)
    assert str(error.value) == f"{path}: line 5, column pressure_kpa: {expected}"


def test_a_table_of_many_rows_is_parsed_alike_by_the_fast_parser(tmp_path):
    rng = np.random.default_rng(1)
    n = measured.LARGE_TABLE_ROWS + 7
    v = np.sort(rng.uniform(0, 30, n))
    v[0] = 0.0
    table = np.column_stack([v, rng.uniform(0, 90, n), rng.uniform(20, 40, n)])
    path = tmp_path / "long.csv"
    with open(path, "w") as handle:
        handle.write(HEADER + "\n")
        np.savetxt(handle, table, fmt="%.17g", delimiter=",")
    lines = path.read_text().splitlines()[1:]
    by_pandas = measured._parsed_by_pandas(lines)
    np.testing.assert_array_equal(by_pandas, table)  # exact: the file holds every digit
    np.testing.assert_array_equal(read_csv_table(path), table)
