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
"""

from __future__ import annotations

ALLOWED: dict[str, dict[str, int]] = {
    "bench/app/certificate/equipment.py": {"json_map_signatures": 2},
    "bench/app/dcc/admin.py": {"json_map_signatures": 1},
    "bench/app/dcc/used_methods.py": {"json_map_signatures": 1},
    "bench/app/records/assurance.py": {"json_map_signatures": 2},
    "bench/app/records/checks.py": {"json_reads": 1},
    "bench/app/records/extract.py": {"json_map_signatures": 4},
    "bench/app/records/hooks.py": {"json_map_signatures": 3},
    "bench/app/session.py": {"json_reads": 1},
    "bench/app/station/live.py": {"json_map_signatures": 1, "json_reads": 1},
    "bench/core/journal.py": {"json_map_signatures": 1, "json_reads": 1},
    "bench/core/registry.py": {"json_map_signatures": 1},
    "bench/kind/__init__.py": {"json_map_signatures": 2},
    "bench/report/certificate/parts.py": {"json_map_signatures": 1},
    "bench/report/station.py": {"json_map_signatures": 1},
    "procedures/base.py": {"json_map_signatures": 1},
    "procedures/drift_pulse/kind.py": {"json_map_signatures": 2},
    "procedures/drift_pulse/records.py": {"json_map_signatures": 1},
    "procedures/drift_pulse/sample.py": {"json_map_signatures": 1},
    "procedures/rate_ladder/kind.py": {"json_map_signatures": 1},
    "procedures/rate_ladder/sample.py": {"json_map_signatures": 3},
    "procedures/rate_ladder/station.py": {"json_map_signatures": 1},
}
