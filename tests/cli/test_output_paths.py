"""Every command that writes a file refuses a path holding a run file (any HDF5 file it
did not make) unless told ``--overwrite``, and never one a run is writing; a name that
would show as something else, a read-only folder or a full device is one line."""

import h5py
import pytest

from labrig.cli import main
from tests.recording.test_run_file_lock import live_run  # noqa: F401  (a fixture)
from tests.support.simulated_runs import tiny_run


def run(argv, capsys):
    with pytest.raises(SystemExit) as exited:
        main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return exited.value.code, out, err


@pytest.fixture(scope="module")
def done(tmp_path_factory):
    return tiny_run(tmp_path_factory.mktemp("done") / "done.h5")


def writers(done, target):
    """Each command that writes a file, aimed at ``target``."""
    return {
        "runs --csv": ["runs", done, "--csv", target],
        "track --out": ["track", "clip.avi", "--mm-per-px", "0.1", "--out", target],
        "plot -o": ["plot", done, "-o", target],
        "frames -o": ["frames", done, "--at-transitions", "-o", target],
        "model scan --out": ["model", "scan", "--n", "2", "--out", target],
    }


@pytest.mark.parametrize(
    "command", ["runs --csv", "track --out", "plot -o", "frames -o", "model scan --out"]
)
def test_a_run_file_is_never_written_over(done, tmp_path, capsys, command):
    target = tiny_run(tmp_path / "RUN.h5")
    before = target.read_bytes()
    argv = writers(done, target)[command]
    code, out, err = run(argv, capsys)
    option = command.split()[-1]
    advice = "" if command == "model scan --out" else ", or --overwrite to replace it"
    assert (code, out, err) == (
        2,
        "",
        f"error: {option} {target}: holds an HDF5 file (a run file?), which this command "
        f"never writes over; choose another name{advice}\n",
    )
    assert target.read_bytes() == before


def test_export_never_writes_over_a_run_file_among_its_names(done, tmp_path, capsys):
    folder = tmp_path / "csv"
    folder.mkdir()
    held = tiny_run(folder / "transitions.csv")  # a run file under a name export writes
    before = held.read_bytes()
    code, _, err = run(["export", done, "--csv", folder], capsys)
    assert code == 2 and "holds an HDF5 file" in err and len(err.splitlines()) == 1
    assert held.read_bytes() == before
    code, _, _ = run(["export", done, "--csv", folder, "--overwrite"], capsys)
    assert code == 0 and held.read_text().startswith("repetition,")


def test_overwrite_lets_a_finished_run_file_go(done, tmp_path, capsys):
    target = tiny_run(tmp_path / "RUN.h5")
    code, _, _ = run(["runs", done, "--csv", target, "--overwrite"], capsys)
    assert code == 0
    assert target.read_text().startswith("file,")


def test_a_live_run_file_is_refused_even_with_overwrite(done, live_run, capsys):  # noqa: F811
    path, writer = live_run
    before = path.read_bytes()
    soft, hard = path.with_name("soft.h5"), path.with_name("hard.h5")
    soft.symlink_to(path)
    hard.hardlink_to(path)
    for target in (path, soft, hard):
        code, _, err = run(["runs", done, "--csv", target, "--overwrite"], capsys)
        assert (code, err) == (
            2,
            f"error: --csv {target}: a labrig run is writing this file; choose another name\n",
        )
    assert path.read_bytes() == before
    writer.communicate("\n", timeout=60)
    with h5py.File(path, "r") as f:
        assert f["entry/status"][()] == b"complete"


@pytest.mark.parametrize("name", ["a\nb.csv", "runs\u202evsc.h5", "tab\there.csv"])
def test_a_name_that_shows_as_another_is_refused(done, tmp_path, capsys, name):
    target = tmp_path / name
    code, _, err = run(["runs", done, "--csv", target], capsys)
    assert code == 2
    (line,) = err.splitlines()
    assert "is a control or a text-direction mark" in line
    assert not target.exists()


def test_a_full_device_is_one_line(done, capsys):
    code, _, err = run(["runs", done, "--csv", "/dev/full"], capsys)
    assert (code, err) == (2, "error: --csv /dev/full: cannot write it (No space left on device)\n")
