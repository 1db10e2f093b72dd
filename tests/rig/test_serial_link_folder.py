"""The simulated pump's link folder does not outlive a killed run: the next simulated
rig removes the folders of processes that are gone, and only those."""

import os
import signal
import subprocess
import sys
import tempfile
import textwrap

from support.simrig import SHORT

from labrig.config.protocol import load_protocol
from labrig.config.rig_file import sim_rig_config
from labrig.rig.serial_link_folder import PREFIX, remove_stale_link_folders
from labrig.rig.simulated import build_simulated_rig

PROTOCOL = SHORT.format(max_pressure_kpa=95, camera_fps=0)

# a simulated rig built in a process of its own, which says where its pump is and waits
# to be killed
CHILD = textwrap.dedent(
    """\
    import sys, time
    from labrig.config.protocol import load_protocol
    from labrig.config.rig_file import sim_rig_config
    from labrig.rig.simulated import build_simulated_rig

    loaded = load_protocol(sys.argv[1])
    rig = build_simulated_rig(loaded.protocol, sim_rig_config())
    print(rig.simulation.emulator.port, flush=True)
    time.sleep(600)
    """
)


def test_a_killed_runs_link_folder_is_removed_by_the_next_rig(tmp_path, monkeypatch):
    protocol_path = tmp_path / "protocol.yaml"
    protocol_path.write_text(PROTOCOL)
    temp = tmp_path / "temp"
    temp.mkdir()
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(protocol_path)],
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "TMPDIR": str(temp)},
    )
    try:
        link = child.stdout.readline().strip()
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait()
        child.stdout.close()
    stale = os.path.dirname(link)
    assert os.path.dirname(stale) == str(temp)
    assert os.path.basename(stale).startswith(f"{PREFIX}{child.pid}-")
    assert os.path.islink(link)  # the killed process could not remove it

    monkeypatch.setattr(tempfile, "tempdir", str(temp))
    rig = build_simulated_rig(load_protocol(protocol_path).protocol, sim_rig_config())
    try:
        assert not os.path.lexists(link)
        assert not os.path.exists(stale)
        port = rig.simulation.emulator.port
        assert os.path.basename(os.path.dirname(port)).startswith(f"{PREFIX}{os.getpid()}-")
        assert os.path.islink(port)
    finally:
        rig.close()
    assert os.listdir(temp) == []  # the new rig's own folder goes with it


def test_only_the_folders_of_processes_gone_are_removed(tmp_path):
    ended = subprocess.Popen([sys.executable, "-c", "pass"])
    ended.wait()  # reaped: its process id names no process now
    gone, alive = ended.pid, os.getpid()
    folders = {
        "gone": tmp_path / f"{PREFIX}{gone}-a1b2_c3",
        "alive": tmp_path / f"{PREFIX}{alive}-d4e5f6",
        "gone with a file": tmp_path / f"{PREFIX}{gone}-g7h8",
        "unnamed": tmp_path / f"{PREFIX}x9y8z7w6",
    }
    for folder in folders.values():
        folder.mkdir()
        (folder / "usb-pump").symlink_to("/dev/pts/does-not-exist")
    (folders["gone with a file"] / "notes.txt").write_text("not a link: not ours to delete")

    assert remove_stale_link_folders(tmp_path) == [folders["gone"]]
    assert not folders["gone"].exists()
    assert (folders["alive"] / "usb-pump").is_symlink()
    assert (folders["unnamed"] / "usb-pump").is_symlink()
    assert (folders["gone with a file"] / "notes.txt").exists()
