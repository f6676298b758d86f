"""The certificate's figures drawn in a worker process while its document is built and
its PDF is laid out (issue 62: a demo's 8 figures were half of its certificate's time).

`drawn_beside()` gives a `BesideDrawer`, or None where one cannot be used (then
`figure_of` draws each figure in its turn, here, as it always did); its worker starts at
once. While the document is built, `figure_of` hands each figure to the drawer: its
drawing function and arguments, pickled, go to the worker, and the document gets a
Figure whose `png` is a ticket. The PDF renderer asks `png(figure)` for the bytes when
it reaches that figure: the worker's, waiting for it if the worker is drawing it, or
drawn here and then if no worker has started it (each figure is claimed once, by a
worker or here), so the figures are drawn beside the PDF's tables, and the PDF never
waits for a worker still starting.

A figure that does not come out as a PNG (nothing to plot, or malformed data: `figure_of`
then gives nothing, or a note) changes the document's blocks. `png` raises
`NotAsDrawn` then, and the document is built again `looking_up()`: each figure drawn is
taken as it was, and every other is drawn here, so the document is the one built
figure by figure.

The bytes are the same wherever a figure is drawn: matplotlib's Agg canvas, the same
settings and fonts (nothing here changes matplotlib's rcParams), a canvas per figure. The
worker is a fresh interpreter ("spawn": its memory is its own, not a copy of this
process's). `BENCH_FIGURE_WORKERS` sets the number of workers (default 1: the PDF, laid
out here meanwhile, is the longer part; 0: every figure drawn here, in its turn).
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib
import os
import pickle
import signal
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from typing import TYPE_CHECKING

if TYPE_CHECKING:   # the figures' claims shared by the PDF and its worker (a byte each)
    from multiprocessing.sharedctypes import SynchronizedArray

    Claims = SynchronizedArray[int]

from bench.report.certificate.model import Block, Document, Figure
from bench.report.certificate.parts import FIGURE_DRAWER

#: the environment variable that sets the number of worker processes
ENV_WORKERS = "BENCH_FIGURE_WORKERS"
DEFAULT_WORKERS = 1
#: figures that may be drawn here when the PDF gets to them first (later ones: by workers)
MAX_CLAIMS = 256
_TICKET = b"\x00certificate figure %d\x00"


class NotAsDrawn(Exception):
    """A figure drawn by a worker is not a PNG: the document is to be built again."""


#: in a worker: the figures' claims, shared with the parent (`BesideDrawer._claims`)
_CLAIMS: Claims | None = None  # noqa: F821


def _claim(claims: Claims, index: int) -> bool:
    """Take figure `index` to draw (False: the other side has it). Figures past the claims'
    length are the workers'."""
    if index >= len(claims):
        return True
    with claims.get_lock():
        if claims[index]:
            return False
        claims[index] = 1
        return True


def _draw_claimed(key: bytes, index: int) -> bytes | None:
    """In a worker: `_draw`, unless the parent has drawn that figure itself."""
    return _draw(key) if _CLAIMS is not None and _claim(_CLAIMS, index) else None


def _draw(key: bytes) -> bytes | None:
    """The PNG of one pickled (draw, args), or None for anything else (no figure, or an
    error, which `figure_of` reports when it draws it again here, in its turn)."""
    try:
        draw, args = pickle.loads(key)
        png = draw(*args)
    except Exception:  # noqa: BLE001 - drawn again in the parent, where figure_of says what
        return None
    return png if isinstance(png, bytes) and png else None


def _worker_started(claims: Claims) -> None:
    """A worker leaves an interrupt to its parent, and loads what every figure needs (a
    kind's plots module is loaded with its first figure's drawing function)."""
    global _CLAIMS
    _CLAIMS = claims
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    import matplotlib.backends.backend_agg  # noqa: F401
    import matplotlib.figure  # noqa: F401

    import bench.report.certificate.plotting  # noqa: F401


def _started() -> None:
    """The first job: the worker is up."""


class BesideDrawer:
    """The figures of one certificate, drawn by a pool of worker processes, in order; a
    figure the PDF reaches before any worker has started it is drawn here, then (each
    figure is claimed once, by a worker or here: `claims`, shared with the workers)."""

    def __init__(self, pool: ProcessPoolExecutor, claims: Claims) -> None:
        self._pool = pool
        self._claims = claims
        self._drawn: dict[bytes, Future[bytes | None]] = {}  # by pickled (draw, args)
        self._index: dict[bytes, int] = {}                   # its claim
        self._here: dict[bytes, bytes | None] = {}           # drawn here, not by a worker
        self._tickets: dict[bytes, bytes] = {}               # ticket -> pickled (draw, args)
        self._looking_up = False

    # -- figure_of's drawer (bench.report.certificate.parts.FigureDrawer) -------------------
    def blocks(self, caption: str, draw: Callable[..., bytes | None], args: tuple[object, ...],
               width_frac: float) -> list[Block] | None:
        try:
            key = pickle.dumps((draw, args), protocol=pickle.HIGHEST_PROTOCOL)
        except Exception:  # noqa: BLE001 - e.g. a local function: figure_of draws it here
            return None
        if self._looking_up:
            png = self._result(key) if key in self._drawn else None
            return [Figure(png, caption, width_frac)] if png else None
        if key not in self._drawn:
            index = len(self._index)
            try:
                self._drawn[key] = self._pool.submit(_draw_claimed, key, index)
            except RuntimeError:  # the pool is broken or shut down: drawn here
                return None
            self._index[key] = index
        ticket = _TICKET % len(self._tickets)
        self._tickets[ticket] = key
        return [Figure(ticket, caption, width_frac)]

    def _result(self, key: bytes) -> bytes | None:
        """The PNG of a figure handed out: drawn here now if no worker has started it,
        else its worker's (waiting for it)."""
        if key not in self._here and _claim(self._claims, self._index[key]):
            self._here[key] = _draw(key)
        if key in self._here:
            return self._here[key]
        drawing = self._drawn[key]
        while not drawing.done():   # a worker has it: draw the last one nobody has, here
            other = self._last_unclaimed()
            if other is None:
                break
            self._here[other] = _draw(other)
        try:
            return drawing.result()
        except Exception:  # noqa: BLE001 - a worker lost (BrokenProcessPool): drawn here
            return None

    def _last_unclaimed(self) -> bytes | None:
        """The last figure handed out that no worker has started, claimed here (None: none
        left). The workers take figures from the first, this process from the last while
        it waits (issue 62: a worker started early, with the run, was always ahead of the
        PDF, which then only waited while the worker drew every figure in turn)."""
        for key, index in reversed(self._index.items()):
            if index < len(self._claims) and key not in self._here \
                    and _claim(self._claims, index):
                return key
        return None

    # -- for the renderers ---------------------------------------------------------------
    def png(self, fig: Figure) -> bytes:
        """The figure's PNG, waiting for its worker; `NotAsDrawn` if it drew none."""
        key = self._tickets.get(fig.png)
        if key is None:
            return fig.png
        png = self._result(key)
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


def _imported(modules: tuple[str, ...]) -> None:
    """In a worker started early: what the figures' drawing functions need (a kind's
    certificate module and its plots; 1 s and more of a worker's start); in a thread of
    the bench's process, what its certificate needs. A module that cannot be imported is
    left to the import where it is needed, which says why."""
    for name in modules:
        with contextlib.suppress(Exception):
            importlib.import_module(name)


Pool = tuple[ProcessPoolExecutor, "Claims"]
#: workers started early, for the next certificate of this process (`started_early`)
_EARLY: list[Pool] = []


def _start(modules: tuple[str, ...] = ()) -> Pool | None:
    """A pool of worker processes with their claims, started now, or None: no workers
    asked for, or fewer than two processors."""
    workers = _workers()
    if workers == 0 or (os.cpu_count() or 1) < 2:
        return None
    import multiprocessing

    context = multiprocessing.get_context("spawn")
    try:
        claims = context.Array("b", MAX_CLAIMS)
        pool = ProcessPoolExecutor(workers, mp_context=context, initializer=_worker_started,
                                   initargs=(claims,))
        for _ in range(workers):
            # the interpreters start while the document is built (or the bench measures)
            if modules:
                pool.submit(_imported, modules)
            else:
                pool.submit(_started)
    except (OSError, ValueError, RuntimeError):
        return None
    return pool, claims


@contextlib.contextmanager
def started_early(modules: tuple[str, ...] = ()) -> Iterator[None]:
    """The next certificate's workers started now, with `modules` imported, so a run's
    certificate finds them ready (issue 62: a worker's interpreter, matplotlib and the
    kind's plots took 1.5 to 2.5 s of the certificate's wall time, while the PDF's
    tables waited for figures or drew them itself); stopped at the block's end if no
    certificate took them. A run starts them before it measures: the bench's stepping
    thread keeps one processor busy, the other is free. This process's own share (fpdf,
    matplotlib and the kind's plots) is imported meanwhile too (`_loaded_here`)."""
    _loaded_here(modules)
    started = _start(modules)
    if started is not None:
        _EARLY.append(started)
    try:
        yield
    finally:
        if started is not None and started in _EARLY:
            _EARLY.remove(started)
            started[0].shutdown(wait=True, cancel_futures=True)


#: what this process needs for a certificate: its PDF (fpdf) and the figures it draws
HERE = ("bench.app.certificate.pdf", "matplotlib.figure", "matplotlib.backends.backend_agg",
        "bench.report.certificate.plotting")


def _loaded_here(modules: tuple[str, ...]) -> None:
    """`HERE` and `modules` imported in a thread of this process, now (issue 62: 1 to 1.5 s
    of a demo's certificate went on importing them; a run measures meanwhile, waiting on
    its instruments and its simulated clock most of the time). An import that fails here
    fails again, and is reported, where the certificate needs it."""
    threading.Thread(target=_imported, args=(HERE + modules,), name="certificate-imports",
                     daemon=True).start()


def _taken() -> Pool | None:
    """Workers started early, taken by one certificate, else None."""
    try:
        return _EARLY.pop()
    except IndexError:
        return None


@contextlib.contextmanager
def drawn_beside() -> Iterator[BesideDrawer | None]:
    """A drawer with its worker processes for one certificate (started early, else now;
    stopped at the end), or None: no workers asked for, or fewer than two processors."""
    started = _taken() or _start()
    if started is None:
        yield None
        return
    pool, claims = started
    try:
        yield BesideDrawer(pool, claims)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
