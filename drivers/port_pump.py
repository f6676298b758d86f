"""A serial port's input carried into a pipe by a child process, for a reader that takes
it a pipe-full at a time.

Why: a pty's line discipline hands over at most 4 kB a read, and each read takes the
interpreter lock back before the next. A co-simulated FOG streams 50-200 MB of frames a
real second; read piece by piece in the bench's process, the reader waited for the lock
behind the thread computing the stand, and the channel moved only while the bench waited
(the paper ladder, issue 62). A small child interpreter (`_PUMP`, no imports but os and
select, started isolated) does the 4 kB reads in a process of its own, and the pipe (1 MiB
where the system allows) gives the reader up to its whole content in one call. Not `cat`:
pyserial sets VMIN = VTIME = 0, so a read of an empty port returns 0 bytes, which cat takes
for the end of its input; the pump waits on poll() and ends only on a hang-up. The bytes are the port's, in order, unchanged: the raw capture is
what the port received.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import subprocess
import sys

#: fcntl's F_SETPIPE_SZ (Linux; Python's fcntl names it from 3.10 on some builds only)
_F_SETPIPE_SZ = getattr(fcntl, "F_SETPIPE_SZ", 1031)
#: the child's program: copy stdin (the port) to stdout (the pipe) until the port hangs up
#: or the pipe's reader is gone; by splice(2) where the kernel splices from a tty (a third
#: less CPU than read and write: one call and no copy through the pump), else read/write
_PUMP = """
import errno, os, select
p = select.poll()
p.register(0, select.POLLIN)
splice = getattr(os, "splice", None)
while True:
    ev = p.poll()[0][1]
    try:
        if splice is not None:
            try:
                n = splice(0, 1, 1 << 16)
            except OSError as e:
                if e.errno != errno.EINVAL:
                    raise
                splice = None
                continue
        else:
            b = os.read(0, 1 << 16)
            v = memoryview(b)
            while v:
                v = v[os.write(1, v):]
            n = len(b)
    except OSError:
        break
    if not n and ev & (select.POLLHUP | select.POLLERR | select.POLLNVAL):
        break
"""
#: bytes the pipe may hold (the system's pipe-max-size by default, 1 MiB)
PIPE_BYTES = 1 << 20


class PortPump:
    """The pump reading the port's path, its output a pipe whose non-blocking read end
    is `fd`. Closing twice is safe."""

    def __init__(self, port: str) -> None:
        src = os.open(port, os.O_RDONLY | os.O_NOCTTY)
        r, w = os.pipe()
        try:
            with contextlib.suppress(OSError):   # a smaller pipe still works, more calls
                fcntl.fcntl(r, _F_SETPIPE_SZ, PIPE_BYTES)
            self._proc: subprocess.Popen[bytes] | None = subprocess.Popen(
                [sys.executable, "-I", "-S", "-c", _PUMP], stdin=src, stdout=w,
                stderr=subprocess.DEVNULL, close_fds=True,
                # a session of its own: the operator's Ctrl-C (SIGINT to the terminal's
                # process group) is the bench's to handle; a pump killed by it would end
                # the FOG's stream first, and "the pump ended" would be the cause read
                start_new_session=True)
        except BaseException:
            os.close(r)
            raise
        finally:
            os.close(src)
            os.close(w)
        os.set_blocking(r, False)
        self.fd: int | None = r
        self.what = f"the pump of {port}, pid {self._proc.pid}"

    @classmethod
    def start(cls, port: str) -> PortPump | None:
        """A pump for `port`, or None where there is none to be had (not POSIX, a port
        that cannot be opened a second time): the reader then reads the port itself."""
        if os.name != "posix" or not sys.executable:
            return None
        try:
            return cls(port)
        except OSError:
            return None

    def close(self) -> None:
        proc, self._proc = self._proc, None
        if proc is not None:
            proc.terminate()
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(timeout=5.0)
        fd, self.fd = self.fd, None
        if fd is not None:
            os.close(fd)
