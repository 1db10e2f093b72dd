"""The pre-flight check of a rig (``labrig rig check``): every device the rig file
names is reached and read, one line each; nothing moves.

- pump: opened on its port at its address with the real driver, which identifies it;
  then its long version, the syringe it is set to and its rate limits (``irate lim``,
  ``wrate lim``) and its state are read. No reply at the configured address: a bare
  ``ver`` (no address, which every pump on the line answers) says whether a pump is there
  at another address.
- pressure: one second of readings through the real DAQ driver, converted to kPa and
  not zeroed, must read atmospheric within the MPX5100's offset tolerance; a wired
  supply channel is read too (in volts, the driver's conversion undone) and must be
  within the sensor's 4.75-5.25 V. The spread of the ADC's codes at rest is reported
  (their standard deviation in LSB and the commonest codes): a sensor quieter than
  about 0.3 LSB does not dither the ADC, so the zero cannot be averaged below one code
  and long runs of one code at rest are normal, not a frozen input.
- camera: frames until the tracker finds both markers (a camera's first frames may be
  dark while its exposure settles), then the resolution, the frame rate set and the one
  the frames' stamps show (auto exposure may lower it in dim light), and the markers'
  distance in px and in mm at the configured scale.

Each failure says what was expected, what was found and what to check (cable, port,
address, driver). The checks take their connections as parameters (a port, a DAQ task
factory, a camera), which is where the simulated rig plugs in (``labrig.rig.check_sim``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from labrig.config.rig_file import CameraConfig, PressureConfig, PumpConfig, RigConfig
from labrig.errors import DeviceError, InputError
from labrig.time.clock import Clock

CAMERA_FRAMES = 10  # frames tried before both markers must have been found, and read
# a measured frame rate below this share of the one set is reported as short
RATE_SHORT = 0.9
# below this spread (LSB) the noise no longer dithers the ADC: a mean of the codes is
# off the true level by up to half a code (a uniform quantisation error is 0.29 LSB)
DITHER_LSB = 0.3
# the commonest codes listed
CODES_SHOWN = 4


@dataclass(frozen=True)
class DeviceCheck:
    """One device's verdict: what was found, and on failure what was expected and
    what to check."""

    device: str
    ok: bool
    found: str
    expected: str = ""
    check: str = ""

    def line(self) -> str:
        if self.ok:
            return f"{self.device:<9} ok    {self.found}"
        return f"{self.device:<9} FAIL  {self.found}; expected {self.expected}; check {self.check}"


def report(checks: list[DeviceCheck]) -> tuple[str, int]:
    """The lines to print and the exit code: 0 when every device passed, else 2."""
    failed = [c.device for c in checks if not c.ok]
    summary = f"rig check: {len(checks) - len(failed)} of {len(checks)} devices ok"
    if failed:
        summary += f"; failed: {', '.join(failed)}"
    return "\n".join([*(c.line() for c in checks), summary]), 2 if failed else 0


# --- the pump ---------------------------------------------------------------------------
def pump_address_on_line(port: str, baud: int, timeout_s: float) -> int | None:
    """The address of a pump that answers a bare ``ver`` on ``port`` (None: nothing
    answers). Every pump answers a command without an address; its prompt carries its
    own address (none at address 0)."""
    import time

    import serial

    from labrig.drivers.phd_ultra import READ_SLICE_S
    from labrig.drivers.phd_ultra_errors import PumpProtocolError
    from labrig.drivers.phd_ultra_protocol import frame_command, parse_reply

    try:
        with serial.serial_for_url(port, baudrate=baud, timeout=READ_SLICE_S) as line:
            line.reset_input_buffer()
            line.write(frame_command("ver", address=0, address_form="none"))
            raw, deadline = b"", time.monotonic() + timeout_s
            while time.monotonic() < deadline:
                raw += line.read(line.in_waiting or 1)
                reply = parse_reply(raw, expect_payload=True, command="ver") if raw else None
                if reply is not None:
                    return reply.address or 0
    except (serial.SerialException, OSError, PumpProtocolError):
        return None
    return None


def check_pump(
    config: PumpConfig,
    clock: Clock,
    port: str | None = None,
    timeout_s: float | None = None,
    search_timeout_s: float | None = None,
) -> DeviceCheck:
    """The pump at ``config.address`` on ``port`` (default: the configured port), each
    reply awaited ``timeout_s`` (host time; default the rig file's ``reply_timeout_s``,
    as a run awaits it); with no reply, a pump at another address awaited
    ``search_timeout_s`` (default ``timeout_s``)."""
    from labrig.drivers.phd_ultra import PhdUltra
    from labrig.drivers.phd_ultra_errors import PumpPortError, PumpTimeout

    port = port or config.port
    timeout_s = config.reply_timeout_s if timeout_s is None else timeout_s
    expected = f"a PHD ULTRA at address {config.address} on {port} ({config.baud} baud)"
    try:
        pump = PhdUltra.open(
            port,
            baudrate=config.baud,
            address=config.address,
            address_form=config.address_form,
            clock=clock,
            timeout_s=timeout_s,
            # a pre-flight check moves nothing: it neither stops a running pump nor
            # changes its mode (a run does both, and says so)
            take_control=False,
        )
    except PumpPortError as exc:
        return DeviceCheck(
            "pump",
            False,
            str(exc),
            expected,
            "the USB/RS-232 cable, the port name (ls /dev/serial/by-id), permission to "
            "open it (the dialout group), and that no other program holds it",
        )
    except PumpTimeout:
        search_s = timeout_s if search_timeout_s is None else search_timeout_s
        answering = pump_address_on_line(port, config.baud, search_s)
        if answering is not None and answering != config.address:
            return DeviceCheck(
                "pump",
                False,
                f"no reply at address {config.address}; the pump on {port} answers at "
                f"address {answering}",
                expected,
                f"the address: set pump.address: {answering} in the rig file, or "
                f"address {config.address} on the pump",
            )
        return DeviceCheck(
            "pump",
            False,
            f"no reply on {port} at address {config.address}, nor to a command without an address",
            expected,
            f"that the pump is switched on, the cable, the port, and the baud rate (the "
            f"rig file says {config.baud}; compare the pump's own setting)",
        )
    except DeviceError as exc:
        return DeviceCheck(
            "pump", False, str(exc), expected, "that the pump is a PHD ULTRA in Quick Start mode"
        )
    try:
        return _pump_found(pump, config, port, expected)
    except DeviceError as exc:
        return DeviceCheck("pump", False, str(exc), expected, "the cable and the pump's display")
    finally:
        pump.close()


def _pump_found(pump, config: PumpConfig, port: str, expected: str) -> DeviceCheck:
    from labrig.drivers.phd_ultra_protocol import force_limit_pressure_kpa

    serial_number = next(
        (
            line.split(":", 1)[1].strip()
            for line in pump.version_details()
            if "serial" in line.lower()
        ),
        "?",
    )
    syringe = pump.syringe
    limits = pump.rate_limits()
    state = pump.status().state.value
    i_lo, i_hi = limits.infuse_ml_min
    if limits.withdraw_ml_min is None:
        withdraw = "no withdraw (infuse-only pump)"
    else:
        w_lo, w_hi = limits.withdraw_ml_min
        withdraw = f"withdraw {w_lo:.3g}-{w_hi:.4g} mL/min"
    force_pct = pump.force_limit_pct()
    backstop_kpa = force_limit_pressure_kpa(force_pct, config.rated_force_n, syringe.diameter_mm)
    found = (
        f"{pump.firmware} (serial {serial_number}) at address {config.address} "
        f"({pump.address_form} form) on {port}; syringe {syringe.diameter_mm:.2f} mm, "
        f"{syringe.volume_ml:g} mL; infuse {i_lo:.3g}-{i_hi:.4g} mL/min, {withdraw}; "
        f"force limit {force_pct} % (stalls above {backstop_kpa:.0f} kPa; a run sets "
        f"{config.force_limit_pct} %); {state}"
    )
    for warning in pump.connect_warnings:
        found += f"; {warning}"
    wanted = config.syringe
    if not (
        math.isclose(syringe.diameter_mm, wanted.diameter_mm, rel_tol=1e-3)
        and math.isclose(syringe.volume_ml, wanted.volume_ml, rel_tol=1e-3)
    ):
        found += (
            f" (the rig file's syringe, {wanted.diameter_mm:g} mm and {wanted.volume_ml:g} "
            "mL, is set when a run starts)"
        )
    if state == "stalled":
        return DeviceCheck(
            "pump", False, found, "an idle pump", "the stall alarm: clear it on the pump"
        )
    if state in ("infusing", "withdrawing"):
        return DeviceCheck(
            "pump",
            False,
            found,
            "an idle pump",
            "what is driving it (another program, a run left going): a run would stop it; "
            f"stop it on the pump's panel or with `labrig pump --port {port} stop`",
        )
    return DeviceCheck("pump", True, found)


# --- the pressure sensor ------------------------------------------------------------------
def _daq_hint(exc: DeviceError, config: PressureConfig) -> tuple[str, str]:
    """(expected, what to check) for a DAQ error, from its DAQmx code."""
    from nidaqmx.error_codes import DAQmxErrors

    from labrig.drivers.ni_daq import DaqNotInstalledError, DaqTimeoutError, DaqUnreachableError

    device = config.channel.strip("/").split("/")[0]
    code = getattr(exc.__cause__, "error_code", None)
    if isinstance(exc, DaqNotInstalledError):
        return "the NI-DAQmx driver", "`python -m nidaqmx installdriver` (or run with --sim)"
    if isinstance(exc, DaqUnreachableError):
        return (
            f"the DAQ {device} reachable",
            f"its USB cable and light, and that nilsdev (or NI MAX) lists it as {device}",
        )
    if code == DAQmxErrors.INVALID_DEVICE_ID.value:
        return (
            f"a DAQ named {device}",
            f"the DAQ's USB cable and its name in NI MAX (pressure.channel: {config.channel})",
        )
    if code == DAQmxErrors.PHYSICAL_CHAN_DOES_NOT_EXIST.value:
        return f"the channel {config.channel}", "pressure.channel against the DAQ's inputs"
    if isinstance(exc, DaqTimeoutError):
        return (
            "samples within the read timeout",
            "the USB cable; that no other program uses the DAQ",
        )
    return (
        f"{config.channel} in {config.terminal}, {config.min_v:g} to {config.max_v:g} V",
        "pressure.terminal, min_v and max_v against the wiring",
    )


def _reading(driver, clock: Clock, seconds: float):
    """Every sample of ``seconds`` of acquisition (a ``PressureBlock``)."""
    driver.start()
    try:
        clock.sleep(seconds)
        return driver.read()
    finally:
        driver.stop()


def check_pressure(
    config: PressureConfig,
    clock: Clock,
    *,
    task_factory: Callable[[], Any] | None = None,
    reader_factory: Callable[[Any], Any] | None = None,
    seconds: float = 1.0,
) -> DeviceCheck:
    """``seconds`` of the sensor through the real driver, not zeroed: atmospheric
    within the MPX5100's tolerance; the supply in volts when a channel measures it."""
    from labrig.drivers import mpx5100
    from labrig.drivers.ni_daq import NiDaqPressure

    def driver(channel: str, supply_channel: str | None, supply_v: float):
        return NiDaqPressure(
            clock,
            channel,
            terminal=config.terminal,
            min_v=config.min_v,
            max_v=config.max_v,
            supply_channel=supply_channel,
            supply_v=supply_v,
            task_factory=task_factory,
            reader_factory=reader_factory,
        )

    tolerance = mpx5100.ACCURACY_KPA
    try:
        sensor = driver(config.channel, config.supply_channel, config.supply_v)
        block = _reading(sensor, clock, seconds)
        # what DAQmx set up, which may differ from what the rig file asks for
        (low_v, high_v), bits = sensor.adc_ranges_v[0], sensor.adc_bits[0]
        where = (
            f"{config.channel} ({config.terminal}, {low_v:g} to {high_v:g} V at {bits} bits, "
            f"{sensor.sample_clock_hz:g} S/s)"
        )
        good = ~np.asarray(block.out_of_range, dtype=bool)
        n, flagged = len(block), int(np.count_nonzero(~good))
        p_kpa = float(np.mean(block.pressure_kpa[good])) if good.any() else float("nan")
        supply = ""
        supply_v = None
        if config.supply_channel is not None:
            # the supply channel read as if it were a sensor output at the nominal
            # supply; the inverse transfer function gives back its volts
            as_kpa = _reading(
                driver(config.supply_channel, None, mpx5100.NOMINAL_SUPPLY_V), clock, 0.1
            ).pressure_kpa
            supply_v = float(np.mean(mpx5100.output_v(as_kpa, mpx5100.NOMINAL_SUPPLY_V)))
            supply = f"; supply {supply_v:.3f} V on {config.supply_channel}"
        if good.any():
            volts = mpx5100.output_v(block.pressure_kpa[good], supply_v or config.supply_v)
            supply += f"; {code_spread(volts, low_v, high_v, bits)}"
    except DeviceError as exc:
        expected, check = _daq_hint(exc, config)
        cause = exc.__cause__
        code = getattr(cause, "error_code", None)
        # DAQmx's own words for a known code; the driver's advice is for its own case
        found = f"DAQmx error {code}: {str(cause).strip().splitlines()[0]}" if code else str(exc)
        if expected == "the NI-DAQmx driver":
            found = "NI-DAQmx is not installed on this machine (nidaqmx finds no driver)"
        return DeviceCheck("pressure", False, found, expected, check)
    found = f"{where}: {seconds:g} s, {n} samples, {p_kpa:+.2f} kPa{supply}"
    if (
        supply_v is not None
        and not mpx5100.SUPPLY_RANGE_V[0] <= supply_v <= mpx5100.SUPPLY_RANGE_V[1]
    ):
        return DeviceCheck(
            "pressure",
            False,
            found,
            f"a supply of {mpx5100.SUPPLY_RANGE_V[0]}-{mpx5100.SUPPLY_RANGE_V[1]} V",
            "the sensor's supply wiring and pressure.supply_channel",
        )
    if flagged == n or not abs(p_kpa) <= tolerance:
        return DeviceCheck(
            "pressure",
            False,
            f"{where}: {flagged} of {n} samples beyond the range, reading {p_kpa:+.2f} kPa",
            f"atmospheric pressure, 0 +- {tolerance:g} kPa (the MPX5100's offset tolerance)",
            "that the line is open to atmosphere, the sensor's supply, the channel it is "
            "wired to, the terminal configuration and its output wire (open, it reads "
            "about 104 kPa with the rig's pull-up, 27 kPa without)",
        )
    return DeviceCheck("pressure", True, f"{found}, atmospheric within +-{tolerance:g} kPa")


def code_spread(volts: np.ndarray, low_v: float, high_v: float, bits: int) -> str:
    """The spread of the ADC codes behind ``volts`` (read on a ``bits``-bit converter
    over ``low_v``..``high_v``): their standard deviation in LSB and the commonest
    codes with their share, and a note when the noise is too small to dither."""
    step_v = (high_v - low_v) / 2**bits
    codes = np.rint((np.asarray(volts, dtype=float) - low_v) / step_v).astype(np.int64)
    values, counts = np.unique(codes, return_counts=True)
    order = np.argsort(-counts, kind="stable")[:CODES_SHOWN]
    shares = ", ".join(f"{values[i]}: {100 * counts[i] / codes.size:.0f} %" for i in order)
    std_lsb = float(np.std(codes))
    text = f"codes at rest: std {std_lsb:.2f} LSB over {values.size} codes ({shares})"
    if std_lsb < DITHER_LSB:
        text += " (too quiet to dither the ADC: the zero is known to one code)"
    return text


# --- the camera ---------------------------------------------------------------------------
def _camera_unreachable(exc: Exception, expected: str) -> DeviceCheck:
    return DeviceCheck(
        "camera",
        False,
        str(exc),
        expected,
        "the camera's USB cable, camera.source in the rig file (an index such as 0, or a "
        "video file), and that no other program uses it",
    )


def check_camera(length, config: CameraConfig | None, source: str) -> DeviceCheck:
    """Frames from ``length`` (a ``CameraLength``) until both markers are found."""
    import cv2

    expected = "both markers in view"
    fix = frame = None
    try:
        for _ in range(CAMERA_FRAMES):
            frame = length.frames.read()
            if frame is None:
                break
            fix = length.tracker.track(frame.image)
            if fix.ok:
                break
    except (DeviceError, InputError) as exc:
        return _camera_unreachable(exc, f"frames from {source}")
    if frame is None:
        return DeviceCheck("camera", False, f"{source} gave no frame", "frames", "camera.source")
    height, width = frame.image.shape[:2]
    fps = length.frames.capture.get(cv2.CAP_PROP_FPS)
    fourcc = length.frames.fourcc
    seen = f"{source}: {width}x{height}, {fps:g} fps" + (f" {fourcc}" if fourcc else "")
    if not length.frames.is_file:
        try:  # enough frames for their stamps to tell the rate
            while length.frames.n_frames < CAMERA_FRAMES:
                length.frames.read()
        except DeviceError as exc:
            return _camera_unreachable(exc, f"frames from {source}")
        measured = length.frames.measured_fps
        if measured is not None:
            seen += f" ({measured:.1f} measured"
            if fps > 0 and measured < RATE_SHORT * fps:
                seen += (
                    ": short of the rate set; in dim light auto exposure lowers it, so add "
                    "light or give camera.exposure"
                )
            seen += ")"
    if not fix.ok:
        return DeviceCheck(
            "camera",
            False,
            f"{seen}; markers {fix.status} in {CAMERA_FRAMES} frames",
            expected,
            "that both markers are in view, lit and not covered, and the focus",
        )
    if length.mm_per_px is not None:
        scale = length.mm_per_px
        distance = f"{fix.distance_px:.1f} px = {fix.distance_px * scale:.2f} mm at {scale:g} mm/px"
    else:
        reference = config.reference_distance_mm
        scale = reference / fix.distance_px
        distance = f"{fix.distance_px:.1f} px = {reference:g} mm (reference: {scale:.4g} mm/px)"
    return DeviceCheck("camera", True, f"{seen}; both markers found, {distance}")


# --- the bench rig ------------------------------------------------------------------------
def check_rig(config: RigConfig) -> list[DeviceCheck]:
    """Every device of a real rig, on the host's clock."""
    from labrig.time.clock import RealClock

    clock = RealClock()
    checks = [check_pump(config.pump, clock), check_pressure(config.pressure, clock)]
    if config.camera is not None:
        checks.append(_check_real_camera(config.camera, clock))
    return checks


def _check_real_camera(config: CameraConfig, clock: Clock) -> DeviceCheck:
    import cv2

    from labrig.drivers.camera import CameraLength, FrameSource

    source = f"camera {config.source}"
    # OpenCV's own warnings about a missing device would repeat the line below
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
    try:
        # set up as a run sets it up (size, exposure, focus read back); the rate is the
        # rig file's, if it names one: a check has no protocol
        frames = FrameSource.open(config.source, clock, config.settings(None))
        frames.warmup_frames = config.warmup_frames
    except (DeviceError, InputError) as exc:
        return _camera_unreachable(exc, f"a camera or video at {config.source!r}")
    try:
        length = CameraLength(
            frames, mm_per_px=config.mm_per_px, reference_distance_mm=config.reference_distance_mm
        )
    except InputError:
        frames.close()
        raise
    try:
        return check_camera(length, config, source)
    finally:
        length.close()
