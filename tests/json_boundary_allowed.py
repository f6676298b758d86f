"""Today's JSON offenders outside the codecs (tests/test_json_boundary.py): per file, its
JSON reads and JSON map signatures, generated once by `python -m tests.json_boundary` on
branch h17 (29 Nov 2026, after the drift kind's model). A number may only go down.

Regenerated once at the merge of issue 61's splits (29 Nov 2026): what moved with its code
moved here too (register/store.py's signatures to model.py and trail.py, counter.py's to
counter_setup.py, config.py's to drivers/fog_settings.py); three numbers rose because a
function that passed a JSON map was split in two, each half passing it on
(certificate/authorise.py 4 -> 6 signatures and 5 -> 7 reads, register/service.py 19 -> 20).

Lowered on branch h22 (issue 60, the rate ladder's model): the ladder's result, budgets,
DCC and plots modules and bench/report/uncertainty_names.py left the list, its analysis
went from 6 signatures to 2 (procedures/rate_ladder/codec.py is a codec).

30 Nov 2026: bench/core/schema.py's 11 left with the YAML loader's exemption (issue 60 exempts
the codecs and the YAML loader; tests/json_boundary.py YAML_LOADER, shared with
test_object_annotations).

30 Nov 2026 (issue 60): empty. The analysis returns its typed result and nothing reads
result.json back (helper-40), the station rows, sample results and certificate/DCC leaves
are typed (helper-41), pdf.py's fpdf override is gone (helper-42), and the readers typed
`dict[str, Any]` the guard now sees (ANY_MAPS) read through codecs. A file that gains a
JSON read or a JSON map signature outside the codecs fails the guard.
"""

from __future__ import annotations

ALLOWED: dict[str, dict[str, int]] = {}
