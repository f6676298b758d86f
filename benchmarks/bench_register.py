"""The cost of a login and of an issue at the lab register (issue 53; run on demand).

    python benchmarks/bench_register.py [--repeat 10] [--pg]

Times, as medians and minima over --repeat rounds:
- a login (`authenticate`: the argon2id check, the lockout bookkeeping, its audit entry)
  on an SQLite register in this process, and through `bench register serve` on 127.0.0.1;
- an issue (allocate a number, take the register's time, record the revision with its
  audit entry) through the service, after one login.
With --pg the service's database is a throwaway PostgreSQL (tests/pg_server.py) instead of
an SQLite file. Prints the load average first: compare cases of one run, not runs.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench.app.register import Register  # noqa: E402
from bench.app.register.client import ServiceRegister  # noqa: E402

DIGESTS = {"result.json": "a" * 64, "certificate.pdf": "b" * 64,
           "certificate.dcc.xml": "c" * 64, "certificate.html": "d" * 64}
ADMIN_PW, SIGNER_PW = "keeper-of-keys-1", "signs-every-day-7"


def _timed(fn: Callable[[], object], repeat: int) -> tuple[float, float]:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), min(times)


def _fill(url: str) -> None:
    with Register.open(url) as reg:
        reg.init("admin", "R. Admin", ADMIN_PW)
        admin = reg.authenticate("admin", ADMIN_PW, "admin")
        reg.add_account(admin, "petrov", "P. Petrov", ["signatory"], "set-by-the-admin-1")
        reg.change_password("petrov", "set-by-the-admin-1", SIGNER_PW)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=10)
    ap.add_argument("--pg", action="store_true", help="PostgreSQL behind the service")
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f}; {args.repeat} rounds each")
    tmp = Path(tempfile.mkdtemp(prefix="bench-register-"))
    server = None
    if args.pg:
        from tests.pg_server import PgServer

        server = PgServer().start()
        db = server.create_database("bench_register")
    else:
        db = f"sqlite:///{tmp / 'register.sqlite'}"
    _fill(db)
    with Register.open(db, migrate=False) as local:
        med, low = _timed(lambda: local.authenticate("petrov", SIGNER_PW, "signatory"),
                          args.repeat)
    print(f"login, register in this process ({'PostgreSQL' if args.pg else 'SQLite'}): "
          f"median {med * 1e3:.1f} ms, min {low * 1e3:.1f} ms")
    proc = subprocess.Popen([sys.executable, "-m", "bench", "register", "serve", "--db", db,
                             "--port", "0"], cwd=ROOT, text=True, stdout=subprocess.PIPE)
    try:
        assert proc.stdout is not None
        url = proc.stdout.readline().split()[3]
        with ServiceRegister.connect(url, "benchmark") as reg:
            med, low = _timed(lambda: reg.authenticate("petrov", SIGNER_PW, "signatory"),
                              args.repeat)
            print(f"login through the service: median {med * 1e3:.1f} ms, "
                  f"min {low * 1e3:.1f} ms")
            signer = reg.authenticate("petrov", SIGNER_PW, "signatory")
            n = iter(range(10**6))

            def issue() -> None:
                number = reg.allocate(f"bench-run-{next(n)}", "RT", signer.name)
                reg.begin_issue(signer, number)
                reg.issue(number, 1, signer, DIGESTS, None, {"run_dir": "benchmark"})

            med, low = _timed(issue, args.repeat)
            print(f"issue through the service (allocate, register time, record): median "
                  f"{med * 1e3:.1f} ms, min {low * 1e3:.1f} ms")
    finally:
        proc.terminate()
        proc.wait(timeout=30)
        if server is not None:
            server.stop()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
