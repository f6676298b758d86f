"""`bench register init/user/equipment/audit/grant`: the lab register's command line
(CONTRACT.md). Every change names the acting account (`--as`) and is authenticated with
its password; the register writes the audit entry with it."""

from __future__ import annotations

import argparse
import datetime as dt
import sys
from typing import Any

from bench.app.register.credentials import Passwords
from bench.app.register.schema import ROLES as ROLES_HELP
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


def _date(text: str) -> dt.date:
    try:
        return dt.date.fromisoformat(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected YYYY-MM-DD, got {text!r}") from None


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


def add_parser(sub: Any) -> None:
    p = sub.add_parser("register", help="the lab register: accounts, equipment, audit trail",
                       description="The lab register (docs/register.md): who may sign, the "
                       "equipment inventory, certificate numbers and the audit trail. "
                       "Exit 0 done, 1 the audit trail is broken, 2 refused.")
    rs = p.add_subparsers(dest="register_command", required=True, metavar="WHAT")

    def common(c: argparse.ArgumentParser, acting: bool = True) -> None:
        c.add_argument("--register", metavar="URL", help="the register (default: the lab "
                       "file's register:)")
        c.add_argument("--lab", metavar="FILE", help="lab file naming the register")
        c.add_argument("--password-stdin", action="store_true",
                       help="read the password(s) from standard input, one per line")
        if acting:
            c.add_argument("--as", dest="as_account", required=True, metavar="ACCOUNT",
                           help="the account acting (its password is asked)")

    ini = rs.add_parser("init", help="create or migrate the register with its first admin")
    ini.add_argument("url", help="sqlite:///PATH or postgresql://ROLE@HOST/DB (the owner)")
    ini.add_argument("--admin", required=True, metavar="NAME", help="the first admin account")
    ini.add_argument("--full-name", help="the admin's full name")
    ini.add_argument("--bench-role", metavar="ROLE", help="PostgreSQL: the benches' database "
                     "role, granted read, audit append and issue through functions only")
    ini.add_argument("--password-stdin", action="store_true",
                     help="read the admin's new password from standard input")
    usr = rs.add_parser("user", help="accounts").add_subparsers(
        dest="user_command", required=True, metavar="ACTION")
    ua = usr.add_parser("add", help="add an account (an admin acts)")
    ua.add_argument("name")
    ua.add_argument("--role", action="append", required=True, choices=ROLES_HELP)
    ua.add_argument("--full-name", help="printed under a signature (default: NAME)")
    ua.add_argument("--function", help="the person's function in the laboratory")
    common(ua)
    eq = rs.add_parser("equipment", help="the equipment inventory").add_subparsers(
        dest="equipment_command", required=True, metavar="ACTION")
    ea = eq.add_parser("add", help="record a standard or instrument and its calibration")
    ea.add_argument("serial")
    for k in ("model", "certificate", "issuer"):
        ea.add_argument(f"--{k}", required=True)
    ea.add_argument("--due", required=True, type=_date, help="calibration due, YYYY-MM-DD")
    common(ea)
    el = eq.add_parser("list", help="the inventory with each item's status today")
    common(el, acting=False)
    ed = eq.add_parser("deviation", help="allow an item past its due date (quality acts)")
    ed.add_argument("serial")
    ed.add_argument("--reason", required=True)
    ed.add_argument("--expires", required=True, type=_date, help="YYYY-MM-DD")
    common(ed)
    au = rs.add_parser("audit", help="check the audit trail's chain; exit 1 when broken")
    common(au, acting=False)
