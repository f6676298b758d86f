"""`bench register init/user/equipment/audit/grant`: the lab register's command line
(CONTRACT.md). Every change names the acting account (`--as`) and is authenticated with
its password; the register writes the audit entry with it. The options:
bench/app/parsers.py."""

from __future__ import annotations

import argparse
import datetime as dt
import sys

from bench.app.register.credentials import Passwords
from bench.app.register.store import Account, Register, RegisterError, redact

EXIT_OK, EXIT_BROKEN, EXIT_REFUSED = 0, 1, 2


def register_url(args: argparse.Namespace) -> str:
    """--register URL, else the lab file's `register:` (--lab FILE, else $BENCH_LAB_SETTINGS)."""
    import os

    from bench.core.lab import LabError, load_lab

    if getattr(args, "register", None):
        return str(args.register)
    lab_file = getattr(args, "lab", None) or os.environ.get("BENCH_LAB_SETTINGS")
    if lab_file:
        try:
            url = load_lab(lab_file).register_url
        except LabError as e:
            raise RegisterError(str(e)) from None
        if url:
            return url
        raise RegisterError(f"{lab_file}: names no register (register: URL)")
    raise RegisterError("which register? give --register URL or --lab FILE (its register: key)")


def _acting(reg: Register, args: argparse.Namespace, pw: Passwords, role: str | None) -> Account:
    return reg.authenticate(args.as_account, pw.next(f"password of {args.as_account}: "), role)


def cmd_register(args: argparse.Namespace) -> int:
    try:
        return _run(args)
    except RegisterError as e:
        print(f"bench register: {e}", file=sys.stderr)
        return EXIT_REFUSED


def _run(args: argparse.Namespace) -> int:
    what = args.register_command
    if what == "init":
        reg = Register.open(args.url)
        with reg:
            pw = Passwords(args.password_stdin)
            made = reg.init(args.admin, args.full_name or args.admin,
                            pw.next(f"new password for {args.admin}: "))
            if args.bench_role:
                if not reg.pg:
                    raise RegisterError("--bench-role is for a PostgreSQL register")
                from bench.app.register.pgsql import grant_bench_role

                with reg.engine.begin() as c:
                    for q in grant_bench_role(args.bench_role):
                        c.exec_driver_sql(q)
                reg.append(args.admin, "bench role granted", args.bench_role)
                print(f"granted the bench role {args.bench_role}: read, append to the audit "
                      "trail, allocate numbers and issue through the register's functions")
        print(f"register {redact(args.url)}: " + (f"created, first admin {args.admin}" if made
                                                  else "up to date (it has accounts)"))
        return EXIT_OK
    with Register.open(register_url(args)) as reg:
        pw = Passwords(args.password_stdin)
        if what == "audit":
            report = reg.audit_check()
            for p in report.problems:
                print(f"AUDIT TRAIL BROKEN: {p}")
            print(f"audit trail of {redact(reg.url)}: {report.entries} entries, "
                  + ("chain whole" if report.ok else f"{len(report.problems)} problem(s)"))
            return EXIT_OK if report.ok else EXIT_BROKEN
        if what == "user":
            by = _acting(reg, args, pw, "admin")
            acct = reg.add_account(by, args.name, args.full_name or args.name, args.role,
                                   pw.next(f"initial password for {args.name}: "),
                                   args.function)
            print(f"account {acct.name} ({acct.full_name}): {', '.join(acct.roles)}")
            return EXIT_OK
        if what == "equipment":
            return _equipment(reg, args, pw)
    raise RegisterError(f"unknown register command {what!r}")


def _equipment(reg: Register, args: argparse.Namespace, pw: Passwords) -> int:
    if args.equipment_command == "list":
        today = dt.date.today()
        items = reg.equipment()
        print(f"{'serial':<22} {'model':<26} {'certificate':<22} {'due':<10}  status")
        for e in items:
            dev = e.deviation_on(today)
            status = ("valid" if e.due >= today else
                      f"DEVIATION until {dev.expires} ({dev.reason})" if dev else "OVERDUE")
            print(f"{e.serial:<22} {e.model:<26} {e.certificate:<22} {e.due.isoformat():<10}"
                  f"  {status}")
        print(f"{len(items)} item(s) in {redact(reg.url)}")
        return EXIT_OK
    if args.equipment_command == "add":
        by = _acting(reg, args, pw, None)
        reg.add_equipment(by, args.serial, args.model, args.certificate, args.issuer, args.due)
        print(f"equipment {args.serial}: {args.model}, {args.certificate} ({args.issuer}), "
              f"due {args.due.isoformat()}")
        return EXIT_OK
    by = _acting(reg, args, pw, "quality")
    reg.add_deviation(by, args.serial, args.reason, args.expires)
    print(f"deviation for {args.serial} until {args.expires.isoformat()}: {args.reason}")
    return EXIT_OK

