"""The Digital Calibration Certificate (PTB DCC 3.3.0): certificate.dcc.xml beside the PDF.

    bench.app.dcc.output.write_dcc(run_path, result)   build, sign if configured, validate, write
    bench.app.dcc.validate.validate_dcc(file)          offline XSD + D-SI unit check
    bench.app.dcc.verify.verify_file(file)             schema, signature, values vs result.json

The XML carries the same results as the PDF, unrounded, each value with its D-SI unit and
expanded uncertainty (k = 2), so a customer's asset system reads them without retyping.
How to read it and how a laboratory sets up signing: docs/dcc.md. The package imports
nothing heavy here, so the stand schema can use `bench.app.dcc.settings` cheaply.
"""

from bench.core import rundir_layout as layout

DCC_NAME = layout.CERTIFICATE_DCC
INVALID_NAME = layout.CERTIFICATE_DCC_INVALID
