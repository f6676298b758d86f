"""The certificate's figures drawn in worker processes while its document is built and
its PDF is laid out (issue 62: a demo's 8 figures were half of its certificate's time).

`drawn_beside()` gives a `BesideDrawer`, or None where one cannot be used (then
`figure_of` draws each figure in its turn, here, as it always did). While the document
is built, `figure_of` hands each figure to the drawer: its drawing function and
arguments, pickled, go to a worker, and the document gets a Figure whose `png` is a
ticket. The PDF renderer asks `png(figure)` for the bytes when it reaches that figure,
waiting for that one alone, so the figures are drawn beside the PDF's tables.

A figure that does not come out as a PNG (nothing to plot, or malformed data: `figure_of`
then gives nothing, or a note) changes the document's blocks. `png` raises
`NotAsDrawn` then, and the document is built again `looking_up()`: each figure a worker
drew is taken from it, and every other is drawn here, so the document is the one built
figure by figure.

The bytes are those drawn here: a worker is a fork of this process (the same modules,
matplotlib settings and fonts; "fork" is used only while this process runs a single
thread, so nothing is forked in the middle of another thread's work), and each figure
is drawn on a canvas of its own. `BENCH_FIGURE_WORKERS` sets the number of workers
(default 1: the PDF, laid out here meanwhile, is the longer part; 0: every figure
drawn here, in its turn).
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import pickle
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor

from bench.report.certificate.model import Block, Document, Figure
from bench.report.certificate.parts import FIGURE_DRAWER

#: the environment variable that sets the number of worker processes
ENV_WORKERS = "BENCH_FIGURE_WORKERS"
DEFAULT_WORKERS = 1
_TICKET = b"\x00certificate figure %d\x00"


class NotAsDrawn(Exception):
    """A figure drawn by a worker is not a PNG: the document is to be built again."""


def _draw(key: bytes) -> bytes | None:
    """In a worker: the PNG of one pickled (draw, args), or None for anything else (no
    figure, or an error, which `figure_of` reports when it draws it again here)."""
    try:
        draw, args = pickle.loads(key)
        png = draw(*args)
    except Exception:  # noqa: BLE001 - drawn again in the parent, where figure_of says what
        return None
    return png if isinstance(png, bytes) and png else None


def _worker_started() -> None:
    """A worker leaves an interrupt to its parent, and a termination ends it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


class BesideDrawer:
    """The figures of one certificate, drawn by a pool of worker processes."""

    def __init__(self, pool: ProcessPoolExecutor) -> None:
        self._pool = pool
        self._drawn: dict[bytes, Future[bytes | None]] = {}  # by pickled (draw, args)
        self._tickets: dict[bytes, bytes] = {}               # ticket -> pickled (draw, args)
        self._looking_up = False

    # -- figure_of's drawer (bench.report.certificate.parts.FigureDrawer) -------------------
    def blocks(self, caption: str, draw: Callable[..., bytes | None], args: tuple[object, ...],
               width_frac: float) -> list[Block] | None:
        try:
            key = pickle.dumps((draw, args), protocol=pickle.HIGHEST_PROTOCOL)
        except Exception:  # noqa: BLE001 - e.g. a local function: figure_of draws it here
            return None
        future = self._drawn.get(key)
        if self._looking_up:
            png = self._png_of(future) if future is not None else None
            return [Figure(png, caption, width_frac)] if png else None
        if future is None:
            try:
                future = self._drawn[key] = self._pool.submit(_draw, key)
            except RuntimeError:  # the pool is broken or shut down: drawn here
                return None
        ticket = _TICKET % len(self._tickets)
        self._tickets[ticket] = key
        return [Figure(ticket, caption, width_frac)]

    @staticmethod
    def _png_of(future: Future[bytes | None]) -> bytes | None:
        try:
            return future.result()
        except Exception:  # noqa: BLE001 - a worker lost (BrokenProcessPool): drawn here
            return None

    # -- for the renderers ---------------------------------------------------------------
    def png(self, fig: Figure) -> bytes:
        """The figure's PNG, waiting for its worker; `NotAsDrawn` if it drew none."""
        key = self._tickets.get(fig.png)
        if key is None:
            return fig.png
        png = self._png_of(self._drawn[key])
        if png is None:
            raise NotAsDrawn(fig.caption)
        return png

    def resolved(self, doc: Document) -> Document:
        """The document with every figure's PNG in place of its ticket."""
        def block(b: Block) -> Block:
            return dataclasses.replace(b, png=self.png(b)) if isinstance(b, Figure) else b
        return dataclasses.replace(doc, sections=tuple(
            dataclasses.replace(s, blocks=tuple(block(b) for b in s.blocks))
            for s in doc.sections))

    @contextlib.contextmanager
    def building(self, looking_up: bool = False) -> Iterator[None]:
        """While a document is built: `figure_of` hands its figures here (`looking_up`:
        takes those drawn, and draws the others in its turn)."""
        self._looking_up = looking_up
        token = FIGURE_DRAWER.set(self)
        try:
            yield
        finally:
            FIGURE_DRAWER.reset(token)


def _workers() -> int:
    try:
        n = int(os.environ.get(ENV_WORKERS, DEFAULT_WORKERS))
    except ValueError:
        n = DEFAULT_WORKERS
    return max(n, 0)


@contextlib.contextmanager
def drawn_beside() -> Iterator[BesideDrawer | None]:
    """A drawer with its worker processes for one certificate (stopped at the end), or
    None: no workers asked for, fewer than two processors, not Linux (fork), or more than
    one thread running here."""
    workers = _workers()
    if (workers == 0 or (os.cpu_count() or 1) < 2 or not sys.platform.startswith("linux")
            or threading.active_count() != 1):
        yield None
        return
    import multiprocessing

    try:
        pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork"),
                                   initializer=_worker_started)
    except (OSError, ValueError):
        yield None
        return
    try:
        yield BesideDrawer(pool)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
