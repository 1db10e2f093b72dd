"""The command list of the PHD ULTRA's Ultra command set, as the emulator answers it.

One row per command: the group the manual files it under, its syntax as the manual
writes it, and where the command is documented (the PHD ULTRA manual 5419-002, the
Ultra-family manual of the Pump 33 DDS 5419-013, or a public client that sends it to a
real pump of the family). ``PumpFirmware`` answers exactly these (a test holds the two
together), and docs/reference/pump.md shows this table (``markdown_table``; a test
checks the page matches).

Not answered: the manual's internal method-transfer commands (``method``, ``mend``,
``mstep``: the pump's own software exports methods with them, no user or client sends
them), and the twin-axis forms of the Pump 33 DDS (``a|b|ab`` arguments).
"""

from __future__ import annotations

from dataclasses import dataclass

# Where each command is documented: the PHD ULTRA manual's pages seen (5419-002
# Rev A: addressing, system commands, status), the PHD ULTRA command list a public
# script quotes from the manual, the Ultra-family manual (Pump 33 DDS, 5419-013), and
# the public clients that send the command to a real pump.
PHD_ULTRA = "PHD ULTRA manual"
LIST = "PHD ULTRA command list"
ULTRA_FAMILY = "Pump 33 DDS manual"
FLOWCHEM = "flowchem (Pump 11 Elite)"
CHEMBOT = "chembot"
CLIENTS = "clients' command lists"


@dataclass(frozen=True)
class Command:
    name: str
    group: str
    syntax: str
    source: str


COMMANDS = (
    Command("address", "system", "address [0-99]", PHD_ULTRA),
    Command("ascale", "system", "ascale [1-100]", LIST),
    Command("baud", "system", "baud [9600|19200|38400|57600|115200]", PHD_ULTRA),
    Command("cat", "system", "cat", PHD_ULTRA),
    Command("dim", "system", "dim [0-100]", LIST),
    Command("echo", "system", "echo [on|off]", CHEMBOT),
    Command("force", "system", "force [1-100]", CHEMBOT),
    Command("metrics", "system", "metrics", FLOWCHEM),
    Command("nvram", "system", "nvram [on|off|none]", CHEMBOT),
    Command("poll", "system", "poll [on|off|remote]", ULTRA_FAMILY),
    Command("remote", "system", "remote [on|off]", CLIENTS),
    Command("time", "system", "time [mm/dd/yy hh:mm:ss]", ULTRA_FAMILY),
    Command("ver", "system", "ver", CHEMBOT),
    Command("version", "system", "version", CHEMBOT),
    Command("load", "method", "load qs {i|w|iw|wi}", LIST),
    Command("lock", "method", "lock [on]", LIST),
    Command("mode", "method", "mode", CLIENTS),
    Command("unlock", "method", "unlock", LIST),
    Command("diameter", "syringe", "diameter [{mm}]", LIST),
    Command("gang", "syringe", "gang [{count}]", ULTRA_FAMILY),
    Command("svolume", "syringe", "svolume [{volume} {ul|ml}]", LIST),
    Command("syrm", "syringe", "syrm [{code} {volume} {units}]", LIST),
    Command("syrmanu", "syringe", "syrmanu ? | syrmanu {code} ?", CLIENTS),
    Command("crate", "run", "crate", LIST),
    Command("irun", "run", "irun", LIST),
    Command("rrun", "run", "rrun", LIST),
    Command("run", "run", "run", LIST),
    Command("status", "run", "status", PHD_ULTRA),
    Command("stop", "run", "stop", LIST),
    Command("stp", "run", "stp", LIST),
    Command("wrun", "run", "wrun", LIST),
    Command("irate", "rate", "irate [max|min|lim|{rate} {units}]", LIST),
    Command("wrate", "rate", "wrate [max|min|lim|{rate} {units}]", LIST),
    Command("civolume", "volume", "civolume", LIST),
    Command("ctvolume", "volume", "ctvolume", FLOWCHEM),
    Command("cvolume", "volume", "cvolume", LIST),
    Command("cwvolume", "volume", "cwvolume", LIST),
    Command("ivolume", "volume", "ivolume", LIST),
    Command("tvolume", "volume", "tvolume [{volume} {units}]", LIST),
    Command("wvolume", "volume", "wvolume", LIST),
    Command("citime", "time", "citime", LIST),
    Command("ctime", "time", "ctime", LIST),
    Command("cttime", "time", "cttime", CHEMBOT),
    Command("cwtime", "time", "cwtime", LIST),
    Command("itime", "time", "itime", LIST),
    Command("ttime", "time", "ttime [{seconds}|hh:mm:ss]", LIST),
    Command("wtime", "time", "wtime", LIST),
    Command("iramp", "ramp", "iramp [{start} {units} {end} {units} {seconds}]", LIST),
    Command("wramp", "ramp", "wramp [{start} {units} {end} {units} {seconds}]", LIST),
    Command("input", "I/O", "input", LIST),
    Command("output", "I/O", "output {1|2} [hi|lo]", LIST),
    Command("sync", "I/O", "sync [high|low]", LIST),
    Command("valve", "I/O", "valve [on|off|auto]", LIST),
)

# Withdraw commands: what an infuse-only model does not know (flowchem: "Unknown
# command" for a withdraw command sent to an infuse-only pump).
WITHDRAW_COMMANDS = frozenset(
    {"wrate", "wrun", "rrun", "wvolume", "cwvolume", "wtime", "cwtime", "wramp"}
)


def markdown_table() -> str:
    """The command list as the table in docs/reference/pump.md."""
    rows = ["| group | command | syntax | documented in |", "|---|---|---|---|"]
    rows += [
        f"| {c.group} | `{c.name}` | `{c.syntax.replace('|', '&#124;')}` | {c.source} |"
        for c in COMMANDS
    ]
    return "\n".join(rows) + "\n"
