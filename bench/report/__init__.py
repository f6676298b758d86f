"""The report vocabulary a procedure kind writes in: certificate blocks and parts, the
rounding rule, conformity decisions, uncertainty budgets and the DCC's XML pieces.

Kinds (`procedures/`) build their certificate sections and DCC results from these; the
applications in `bench.app` render them. Imports `bench.core`, `bench.analysis` and below.
"""
