"""A third procedure kind, `dwell`, written the way README "How to add a procedure" says:
a package of its own (this one), registered by one entry point line, as an installed
package would register it:

    [project.entry-points."ratebench.procedures"]
    dwell = "tests.plugin_kind:KIND"

(tests/test_procedure_plugin.py registers it so). It imports only what a procedure may
(the engine's interfaces, the certificate's and the DCC's vocabulary, the kind interface
bench/kind.py, procedures.base). Its plan is one step that waits on the bench clock; no
instrument is opened. On twins (a stand file with a `sim:` block, or `--sim`) that clock
is the simulated bench's, which has no twin to start. Its analysis reads the journal back
and states two figures, the time waited and its error against the dwell asked for, the
error checked against a tolerance.

A kind is a name and its parts, each an attribute with its own interface (bench/kind.py
`Kind`), each checked by mypy where `KIND` is declared: `settings` (its files), `plan`,
`steps` (one handler per action; the plan is checked against them when built),
`analysis` (kind.py), `certificate`, `dcc`, `records` and `station` (report.py). Its
journal record is declared in events.py, where the journal codec finds it. Its figures
reach the records, `bench history`, the trend plot and the console summary through their
declaration alone (the `records` part, a `bench.report.figures.DeclaredFigures`).

`KIND` has a DCC part of its own; `QUIET` is the same kind with the neutral
`DccParts()`, which still gives a valid DCC.
"""

from tests.plugin_kind.kind import KIND, NAME, QUIET
from tests.plugin_kind.report import FIGURES

__all__ = ["FIGURES", "KIND", "NAME", "QUIET"]
