"""The faults a FOG twin injects on purpose, by stand sample (sims/fog_twin.py inject),
and the hold a stall puts in the twin's output queue (sims/fog_line.py).

A fault is recorded in the twin's truth, so a test can compare what the driver decoded
with what the twin sent.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Corrupt:
    """Frames sample .. sample+count-1 go out with one byte xor-ed (their CRC fails)."""

    sample: int
    count: int = 1
    byte: int = 14          # offset in the frame; 0..3 breaks the header instead
    xor: int = 0x5A


@dataclass(frozen=True)
class Drop:
    """Frames sample .. sample+count-1 are never sent (the counter still advances)."""

    sample: int
    count: int = 1


@dataclass(frozen=True)
class Garbage:
    """nbytes of noise go out just before frame `sample` (no frame is lost).

    With `decoys`, the noise carries header patterns and a cut-off frame, the worst
    case for resynchronisation.
    """

    sample: int
    nbytes: int
    seed: int = 0
    decoys: bool = True


@dataclass(frozen=True)
class Stall:
    """The output stops at frame `sample` for duration_s (stand seconds).

    lose=False: the frames are held and go out late (a blocked link).
    lose=True: the frames of that time are never sent (the unit stopped transmitting
    while its counter ran).
    """

    sample: int
    duration_s: float
    lose: bool = False


Fault = Corrupt | Drop | Garbage | Stall


@dataclass(frozen=True)
class Hold:
    """A stall's place in the output queue: the frames after it wait until the stand's
    clock reaches until_s (a blocked link)."""

    until_s: float
