"""What public clients of the PHD ULTRA / Pump 11 Elite family send, byte for byte, and
what a pump answers them: each client's own sequence (connect, set up, infuse, poll,
stop) with its own address form, prefix and line ending, as expected-protocol tables.

Rebuilt from the clients' code (their command strings and number formats), not
imported from it. ``b""`` as the command is a reply the pump sends by itself; a row
``(WAIT, seconds)`` is clock time the client lets pass. The answers are the emulator's
(``tests/sim/test_pump_conformance.py`` replays them on a pseudo-terminal and through
the driver's parser; ``tests/cli/test_pump_cli.py`` against ``labrig pump emulate``).
"""

from __future__ import annotations

WAIT = "wait"  # a row (WAIT, seconds): the client lets clock time pass

METRICS = (
    b"\n00:Pump type          PHD ULTRA\r\n00:Pump type string   PHD ULTRA I/W\r"
    b"\n00:Min syringe size   0.1 mm\r\n00:Max syringe size   50 mm\r"
    b"\n00:Direction          Infuse/withdraw\r\n00:Programmable       Yes\r"
    b"\n00:Limit switches     No\r\n00:"
)

# flowchem's Elite11InfuseWithdraw at address 0: `f"{address}{command} {argument}\r\n"`,
# every reply line read as two address digits, a prompt character and the body.
# Address discovery, initialize() (stop, syringe, version, clear, metrics twice), then
# set_flow_rate("0.5 ml/min"), infuse(), a poll, the infused volume, stop().
FLOWCHEM_ELITE11 = [
    (b"\r\n", b"\n00:"),  # autodiscover_address: an empty line
    (b"0stp \r\n", b"\n00:"),
    (b"0diameter 14.5670 mm\r\n", b"\n00:"),
    (b"0svolume 10.000000000000000 m\r\n", b"\n00:"),
    (b"0VER \r\n", b"\n00:PHD ULTRA 3.0.5\r\n00:"),
    (b"0ctvolume \r\n", b"\n00:"),  # set_target_volume("0 ml")
    (b"0civolume \r\n", b"\n00:"),
    (b"0cwvolume \r\n", b"\n00:"),
    (b"0metrics \r\n", METRICS),
    (b"0metrics \r\n", METRICS),  # InfuseWithdraw asserts the Direction line
    # (14.567 / 9.525)^2 times the reference limits 14.7792 nl/min, 15.3477 ml/min
    (b"0irate lim \r\n", b"\n00:34.567 nl/min to 35.8966 ml/min\r\n00:"),
    (b"0irate 0.5000000000 m/m\r\n", b"\n00:"),
    (b"0irate \r\n", b"\n00:500 ul/min\r\n00:"),
    (b"0  \r\n", b"\n00:"),  # is_moving(): an empty command, the prompt read
    (b"0irun \r\n", b"\n00>"),
    (WAIT, 6.0),  # 0.5 mL/min for 6 s: 50 uL
    (b"0  \r\n", b"\n00>"),
    (b"0ivolume \r\n", b"\n00>50 ul\r\n00>"),
    (b"0crate \r\n", b"\n00>500 ul/min\r\n00>"),
    (b"0stp \r\n", b"\n00:"),
]

# chembot's SyringePumpHarvard on a PHD ULTRA over USB, no address, `"@" + command +
# "\r"`: activate (NVRAM off, diameter), write_infuse(1 mL at 1 mL/min), polls of
# `status`, the target's own prompt, stop to silence it, then the counters.
CHEMBOT_INFUSE = [
    (b"@NVRAM off\r", b"\n:"),
    (b"@diameter 14.5670\r", b"\n:"),
    (b"@civolume\r", b"\n:"),
    (b"@citime\r", b"\n:"),
    (b"@cttime\r", b"\n:"),
    (b"@tvolume 1.0000 ml\r", b"\n:"),
    (b"@irate 1.0000 ml/min\r", b"\n:"),
    (b"@irun\r", b"\n>"),
    (WAIT, 30.0),
    # 1 mL/min = 1e12 fL / 60 s; 30 s run; 0.5 mL = 5e11 fL
    (b"@status\r", b"\n16666666667 30 500000000000 I..TI.\r\n>"),
    (b"@force\r", b"\n100%\r\n>"),
    (WAIT, 31.0),
    (b"", b"\nT*"),  # the target, 1 mL after 60 s, announced unsolicited
    (b"@status\r", b"\n0 60 1000000000000 i..TIT\r\nT*"),
    (b"@stop\r", b"\n:"),
    (b"@ivolume\r", b"\n1 ml\r\n:"),
    (b"@itime\r", b"\n00:01:00\r\n:"),
    (b"@ttime\r", b"\nTarget time not set\r\n:"),
    (b"@iramp\r", b"\nRamp not set up\r\n:"),
]

# Pico Plus code of the same family (BioCAT): `f"{address:02d}{command}\r"`, NVRAM
# writes off with `nvram none`, a rate in a unit of its choosing, counters read back.
PICO_PLUS = [
    (b"00ver\r", b"\nPHD ULTRA 3.0.5\r\n:"),
    (b"00nvram none\r", b"\n:"),
    (b"00diameter\r", b"\n26.7000 mm\r\n:"),
    (b"00irate 90 ul/hr\r", b"\n:"),
    (b"00irate\r", b"\n90 ul/hr\r\n:"),
    (b"00tvolume 3 ul\r", b"\n:"),
    (b"00tvolume\r", b"\n3 ul\r\n:"),
    (b"00irun\r", b"\n>"),
    (WAIT, 60.0),  # 90 uL/hr for 60 s: 1.5 uL
    (b"00ivolume\r", b"\n1.5 ul\r\n>"),
    (b"00wvolume\r", b"\n0 ul\r\n>"),
    (b"00stop\r", b"\n:"),
]

# A technician at a terminal (screen, picocom, miniterm: CR on Enter), setting up by
# Quick Start and the syringe table, ramps and the console's system commands.
TECHNICIAN = [
    (b"ver\r", b"\nPHD ULTRA 3.0.5\r\n:"),
    (b"load qs i\r", b"\n:"),
    (b"mode\r", b"\nQuick Start Infuse\r\n:"),
    (b"wrun\r", b"\nCommand error: [wrun]\r\n   Not allowed in Quick Start i\r\n:"),
    (b"load qs iw\r", b"\n:"),
    (b"syrmanu ?\r", b"\nbdp  BD Plastipak\r\nhm1  Hamilton 1000 series\r\n:"),
    (b"syrm bdp 60 ml\r", b"\n:"),
    (b"syrm\r", b"\nbdp 60 ml\r\n:"),
    (b"svol\r", b"\n60 ml\r\n:"),
    (b"gang 3\r", b"\nRange error: 3\r\n   Syringe count out of range of 1 to 2.\r\n:"),
    (b"irate 2 m/h\r", b"\n:"),
    (b"irate\r", b"\n2 ml/hr\r\n:"),
    (b"irate 5 furlongs/min\r", b"\nArgument error: [furlongs/min]\r\n   Unknown argument\r\n:"),
    (b"iramp 1 ml/min 3 ml/min 10\r", b"\n:"),
    (b"iramp\r", b"\n1 ml/min to 3 ml/min in 10 seconds\r\n:"),
    (b"ttime 00:01:40\r", b"\n:"),
    (b"ttime\r", b"\n00:01:40\r\n:"),
    (b"dim 50\r", b"\n:"),
    (b"dim\r", b"\n50%\r\n:"),
    (b"echo\r", b"\nOff\r\n:"),
    (b"address\r", b"\n0\r\n:"),
    (b"baud\r", b"\n115200\r\n:"),
    (b"input\r", b"\nHigh\r\n:"),
    (b"output 1 hi\r", b"\n:"),
    (b"output 1\r", b"\nHigh\r\n:"),
    (b"valve\r", b"\nOff\r\n:"),
    (b"unlock\r", b"\n:"),
    (b"bogus\r", b"\nCommand error: [bogus]\r\n   Unknown command\r\n:"),
]

# A technician with a user method (the emulator's 'prime': 0.5 mL at 6 mL/min, a 10 s
# pause, 0.5 mL): loaded, refused a Quick Start run, started, found standing in its
# pause (idle prompt, flags standing, the target flag clear), refused a new mode while
# it runs, stopped (the pause then never ends in motion), and left for Quick Start.
METHOD = [
    (b"load prime\r", b"\n:"),
    (b"mode\r", b"\nMethod prime\r\n:"),
    (b"irun\r", b"\nCommand error: [irun]\r\n   Not allowed in method prime\r\n:"),
    (b"run\r", b"\n>"),
    (WAIT, 7.0),  # 5 s for the first 0.5 mL, then 2 s into the pause
    (b"status\r", b"\n0 5 500000000000 i..TI.\r\n:"),
    (b"load qs iw\r", b"\nCommand error: [load]\r\n   Not allowed while running\r\n:"),
    (b"stop\r", b"\n:"),
    (WAIT, 20.0),  # past the pause's end: nothing moves
    (b"ivolume\r", b"\n500 ul\r\n:"),
    (b"load qs iw\r", b"\n:"),
    (b"mode\r", b"\nQuick Start Infuse/Withdraw\r\n:"),
]

SEQUENCES = {
    "flowchem Elite11": (FLOWCHEM_ELITE11, {"reply_style": "prefixed"}),
    "chembot infuse": (CHEMBOT_INFUSE, {}),
    "Pico Plus (BioCAT)": (PICO_PLUS, {}),
    "technician": (TECHNICIAN, {}),
    "technician with a method": (METHOD, {}),
}
