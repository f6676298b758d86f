"""What goes wrong with an axis, as the driver (drivers/axis.py) raises it: each error
names the axis and what, and says whether the axis may still be turning afterwards.
"""

from __future__ import annotations

from drivers.cia402 import AbortReaction


class AxisError(RuntimeError):
    """Something went wrong with an axis drive (names the axis and what).

    `axis_moving`: after this error the axis may still be turning (the stop registry's
    outcome carries it as a field: bench/core/stops.py)."""

    axis_moving: bool = False


class LimitError(AxisError, ValueError):
    """A command over the stand's limits: refused before anything was sent."""


class ObjectRefused(AxisError):
    """The drive answered an SDO with an abort (no such object, value out of range...)."""


#: the words that say, loudly, to the operator that an axis may still be turning
NOT_STOPPED = "COULD NOT BE TOLD TO STOP"


class DriveUnreachable(AxisError):
    """The drive cannot be told to stop (its heartbeat is silent): only its own heartbeat
    watchdog can stop the table now, once our heartbeat stops. Says so loudly."""

    axis_moving = True

    def __init__(self, axis: str, silence_s: float, watchdog_ms: int | None,
                 abort_option: int | None) -> None:
        try:
            reaction = AbortReaction(abort_option).name.lower().replace("_", " ") \
                if abort_option is not None else None
        except ValueError:
            reaction = f"option {abort_option}"
        what = (f"its heartbeat watchdog (0x1016, {watchdog_ms} ms) trips as our heartbeat "
                f"stops now" if watchdog_ms else "it watches no heartbeat of ours (0x1016 "
                "is 0): NOTHING STOPS IT but its own limits")
        then = (f" and reacts with {reaction} (0x6007)" if reaction and watchdog_ms else "")
        super().__init__(
            f"AXIS {axis.upper()} {NOT_STOPPED}: the drive has been silent for "
            f"{silence_s:.2f} s; {what}{then}. Check the table before going near it.")
        self.axis, self.silence_s, self.watchdog_ms = axis, silence_s, watchdog_ms


class AxisTimeout(AxisError, TimeoutError):
    """A wait (settling, standstill, state change) did not finish in time."""


class PositionError(AxisError):
    """A move ended, but not within the position tolerance of its target."""


class DriveFault(AxisError):
    """The drive reported a fault (EMCY), rebooted, or went silent.

    `code` is the EMCY error code (CiA 301/402), e.g. 0x8611 following error; 0x8130
    when the controller stopped hearing the drive's heartbeat.
    """

    def __init__(self, axis: str, node_id: int, code: int | None, description: str,
                 register: int = 0, t_s: float | None = None) -> None:
        self.axis = axis
        self.node_id = node_id
        self.code = code
        self.description = description
        self.register = register
        self.t_s = t_s
        where = f"axis {axis} (drive node {node_id})"
        what = f"0x{code:04X} {description}" if code is not None else description
        super().__init__(f"{where}: drive fault {what}")
