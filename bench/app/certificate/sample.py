"""Preview the certificate of every installed kind that ships a hand-made result
(`sample_result()`, e.g. procedures/rate_ladder/sample.py):
`python -m bench.app.certificate.sample OUT_DIR`.
"""

from __future__ import annotations

import sys
from pathlib import Path

from bench.app.certificate import render_files
from bench.core.registry import procedure_names
from bench.kind import HasSampleResult, installed_records
from bench.report.certificate.sources import Sources
from bench.report.codec import encode


def main(out: Path) -> None:
    for name in procedure_names():
        kind = installed_records(name)
        if isinstance(kind, HasSampleResult):
            sample = encode(kind.sample_result())
            for path in render_files(Sources.load(sample, None), out / name):
                print(path)


if __name__ == "__main__":  # preview: python -m bench.app.certificate.sample OUT_DIR
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "."))
