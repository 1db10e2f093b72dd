"""``labrig pump``: the technician's manual control of the PHD ULTRA, and its emulator.

Each command opens the port, does one thing, reports what the pump says and releases
the port; a run keeps going after the command returns (the pump runs by itself) unless
``--wait`` follows it to the end. The driver and the emulator are imported inside the
commands so that ``labrig --help`` stays instant.
"""

from __future__ import annotations

import signal
import threading

import click

from labrig.errors import DeviceError, InputError

# the emulator's user methods (labrig.sim.pump_methods), named here so that building the
# command line imports no emulator
METHOD_NAMES = ("prime", "rinse")

BAUD_RATES = ("9600", "19200", "38400", "57600", "115200")
# how often --wait asks the pump: a stall sends nothing by itself, so it is polled for
POLL_S = 1.0


@click.group()
@click.option("--port", help="The pump's serial device or pyserial URL (/dev/ttyUSB0, COM3).")
@click.option(
    "--address", type=click.IntRange(0, 99), default=0, show_default=True, help="Pump address."
)
@click.option("--baud", type=click.Choice(BAUD_RATES), default="115200", show_default=True)
@click.option(
    "--address-form",
    type=click.Choice(["auto", "digits", "colon", "none"]),
    default="auto",
    show_default=True,
    help="How the address goes before each command: 00irate, 0:irate, or not at all; "
    "auto: none at address 0 or N:irate elsewhere, then 0Nirate; the answered one is kept.",
)
@click.option(
    "--reply-timeout",
    type=click.FloatRange(min=0, min_open=True),
    default=2.0,
    show_default=True,
    help="Seconds the pump may take to answer one command.",
)
@click.pass_context
def pump(
    ctx: click.Context,
    port: str | None,
    address: int,
    baud: str,
    address_form: str,
    reply_timeout: float,
) -> None:
    """Drive the PHD ULTRA syringe pump by hand, or emulate one."""
    ctx.obj = {
        "port": port,
        "address": address,
        "baud": int(baud),
        "address_form": address_form,
        "timeout_s": reply_timeout,
    }


def _open(ctx: click.Context, *, take_control: bool = False):
    """The pump on ``--port``. ``take_control`` (a manual run): a pump found moving is
    stopped and said so, and put in Quick Start; without it (status, version, stop)
    it is looked at as it is."""
    from labrig.drivers.phd_ultra import PhdUltra

    settings = ctx.obj
    if not settings["port"]:
        raise InputError(
            "labrig pump: --port is required (the pump's serial device, e.g. /dev/ttyUSB0, "
            "or the path 'labrig pump emulate' printed)"
        )
    return PhdUltra.open(
        settings["port"],
        baudrate=settings["baud"],
        address=settings["address"],
        address_form=settings["address_form"],
        timeout_s=settings["timeout_s"],
        take_control=take_control,
    )


@pump.command()
@click.pass_context
def status(ctx: click.Context) -> None:
    """State, volumes since the last clear, rates, target and syringe."""
    with _open(ctx) as driver:
        now = driver.status()
        target_ml = driver.target_volume_ml()
        rows = [
            ("state", now.state.value),
            ("infused", f"{now.infused_ml:.4f} mL"),
            ("withdrawn", f"{now.withdrawn_ml:.4f} mL"),
            ("infuse rate", f"{driver.infuse_rate_ml_min():.6g} mL/min"),
            (
                "withdraw rate",
                f"{driver.withdraw_rate_ml_min():.6g} mL/min"
                if driver.can_withdraw
                else "none (infuse-only pump)",
            ),
            ("force limit", f"{driver.force_limit_pct()} %"),
            ("target", "not set" if target_ml is None else f"{target_ml:.4f} mL"),
            ("diameter", f"{driver.syringe.diameter_mm:.4f} mm"),
            ("syringe", f"{driver.syringe.volume_ml:g} mL"),
        ]
    for name, value in rows:
        click.echo(f"{name:<14} {value}")


@pump.command()
@click.pass_context
def version(ctx: click.Context) -> None:
    """Firmware, address and serial number."""
    with _open(ctx) as driver:
        click.echo(driver.firmware)
        for line in driver.version_details():
            click.echo(line)


@pump.command()
@click.pass_context
def stop(ctx: click.Context) -> None:
    """Stop the motor (also silences a target or stall alarm)."""
    with _open(ctx) as driver:
        driver.stop()
        infused_ml, withdrawn_ml = driver.volumes_ml()
    click.echo(f"stopped: infused {infused_ml:.4f} mL, withdrawn {withdrawn_ml:.4f} mL")


def _run_options(command):
    command = click.option(
        "--wait",
        is_flag=True,
        help="Follow the run until it ends (Ctrl-C stops the pump); without it the "
        "command returns while the pump keeps running.",
    )(command)
    command = click.option(
        "--diameter-mm",
        type=click.FloatRange(min=0, min_open=True),
        help="Set the syringe's inner diameter first.",
    )(command)
    command = click.option(
        "--volume-ml",
        type=click.FloatRange(min=0, min_open=True),
        help="Stop by itself after this volume; without it, run until stopped.",
    )(command)
    return click.option(
        "--rate-ml-min",
        type=click.FloatRange(min=0, min_open=True),
        required=True,
        help="Rate in mL/min, within the syringe's limits.",
    )(command)


@pump.command()
@_run_options
@click.pass_context
def infuse(ctx: click.Context, **options) -> None:
    """Infuse at a rate (to a volume); clears the counters."""
    _run(ctx, "infuse", **options)


@pump.command()
@_run_options
@click.pass_context
def withdraw(ctx: click.Context, **options) -> None:
    """Withdraw at a rate (to a volume); clears the counters."""
    _run(ctx, "withdraw", **options)


def _run(
    ctx: click.Context,
    direction: str,
    *,
    rate_ml_min: float,
    volume_ml: float | None,
    diameter_mm: float | None,
    wait: bool,
) -> None:
    with _open(ctx, take_control=True) as driver:  # a pump found moving: said in the log
        if diameter_mm is not None:
            driver.configure_syringe(diameter_mm, driver.syringe.volume_ml)
        driver.clear_volumes()
        if volume_ml is not None:
            driver.set_target_volume(volume_ml)
        if direction == "infuse":
            driver.set_infuse_rate(rate_ml_min)
            driver.infuse()
        else:
            driver.set_withdraw_rate(rate_ml_min)
            driver.withdraw()
        until = f"until {volume_ml:g} mL" if volume_ml is not None else "until stopped"
        click.echo(f"{direction}: {rate_ml_min:g} mL/min {until}")
        if wait:
            _follow(driver)
        elif volume_ml is None:
            click.echo(f"stop it with: labrig pump --port {ctx.obj['port']} stop")


def _follow(driver) -> None:
    def progress(status) -> None:
        click.echo(
            f"{status.state.value:<14} infused {status.infused_ml:.4f} mL  "
            f"withdrawn {status.withdrawn_ml:.4f} mL"
        )

    try:
        driver.wait_until_stopped(poll_s=POLL_S, on_status=progress)
    except KeyboardInterrupt:
        driver.stop()
        click.echo("stopped the pump", err=True)
        raise click.exceptions.Abort() from None


@pump.command()
@click.option(
    "--speed",
    type=click.FloatRange(min=0, min_open=True),
    default=1.0,
    show_default=True,
    help="Clock speed factor: 10 runs the plunger ten times faster than real time.",
)
@click.option(
    "--address",
    "emulated_address",
    type=click.IntRange(0, 99),
    help="The emulated pump's address [default: the group's --address].",
)
@click.option(
    "--reply-style",
    type=click.Choice(["plain", "prefixed"]),
    default="plain",
    show_default=True,
    help="plain: PHD ULTRA lines; prefixed: each line starts with the address and prompt "
    "(00:), as a Pump 11 Elite answers flowchem.",
)
@click.option(
    "--poll",
    type=click.Choice(["off", "on", "remote"]),
    default="off",
    show_default=True,
    help="The poll mode the pump was left in (on: XON after prompts; remote: no prompts).",
)
@click.option(
    "--strict-address",
    is_flag=True,
    help="Answer only the address forms real pumps take (none, 0 or 00 at address 0; "
    "N:cmd elsewhere) and ignore the others.",
)
@click.option("--infuse-only", is_flag=True, help="An infuse-only model: refuse withdraw commands.")
@click.option(
    "--no-direction",
    is_flag=True,
    help="Firmware whose 'metrics' has no Direction line (it does not say whether it withdraws).",
)
@click.option(
    "--quick-start",
    type=click.Choice(["i", "w", "iw", "wi"]),
    default="iw",
    show_default=True,
    help="The Quick Start variant it was left in (i: infuse only, w: withdraw only).",
)
@click.option(
    "--method",
    type=click.Choice(sorted(METHOD_NAMES)),
    help="A user method it was left in (started with 'run'; 'load qs iw' leaves it).",
)
@click.pass_context
def emulate(
    ctx: click.Context,
    speed: float,
    emulated_address: int | None,
    reply_style: str,
    poll: str,
    strict_address: bool,
    infuse_only: bool,
    no_direction: bool,
    quick_start: str,
    method: str | None,
) -> None:
    """Serve an emulated PHD ULTRA on a pseudo-terminal.

    Prints the device path (/dev/pts/N) on stdout, then serves until Ctrl-C or SIGTERM.
    Any program that opens a serial port can drive it: open that path at 115200 baud,
    8N1, no flow control (a pseudo-terminal takes any baud rate) and send the Ultra
    command set, each command ended by CR, LF or CR LF.

    \b
    A terminal:  picocom -b 115200 /dev/pts/N      (Enter sends CR)
                 screen /dev/pts/N 115200
                 python -m serial.tools.miniterm /dev/pts/N 115200
    flowchem:    labrig pump emulate --reply-style prefixed, then
                 port = "/dev/pts/N" in its Elite11 device configuration
    LabVIEW:     VISA resource ASRL/dev/pts/N::INSTR (Linux), termination CR

    The full list of commands it answers, and a worked example, are in
    docs/reference/pump.md and docs/how-to/pointing-a-program-at-the-pump-emulator.md."""
    from labrig.sim.pump import PumpEmulator
    from labrig.sim.pump_firmware import REAL_ADDRESSING
    from labrig.time.clock import RealClock, ScaledClock

    address = ctx.obj["address"] if emulated_address is None else emulated_address
    clock = RealClock() if speed == 1 else ScaledClock(speed)
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda signum, frame: done.set())
    with PumpEmulator(
        clock,
        address=address,
        reply_style=reply_style,
        poll_mode=poll,
        strict_address_form=REAL_ADDRESSING if strict_address else None,
        infuse_only=infuse_only,
        metrics_direction=not no_direction,
        quick_start=quick_start,
        method=method,
    ) as emulator:
        click.echo(emulator.port)
        click.echo(
            f"PHD ULTRA emulator at address {address}, clock x{speed:g}; Ctrl-C stops it", err=True
        )
        try:
            while emulator.serving and not done.wait(0.5):
                pass
        except KeyboardInterrupt:
            pass
        if not emulator.serving and not done.is_set():
            # never a process that says it serves a port that is gone
            raise DeviceError(f"the emulator stopped serving {emulator.port}")
    click.echo("emulator stopped", err=True)
