"""`bench register init/user/equipment/audit/grant`: the lab register's command line
(CONTRACT.md). Every change names the acting account (`--as`) and is authenticated with
its password; the register writes the audit entry with it. The options:
bench/app/parsers.py."""

from __future__ import annotations

import argparse
import datetime as dt
import sys
from types import FrameType

from bench.app.register.credentials import Passwords
from bench.app.register.store import Account, Equipment, Register, RegisterError, redact

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
            roles = [(k, r) for k in ("service", "bench", "station")
                     for r in getattr(args, f"{k}_role")]
            if roles and not reg.pg:
                raise RegisterError("--service-role/--bench-role/--station-role are for a "
                                    "PostgreSQL register")
            from bench.app.register.pgsql import grants

            for kind, role in roles:
                with reg.engine.begin() as c:
                    for q in grants(kind, role):
                        c.exec_driver_sql(q)
                reg.append(args.admin, f"{kind} role granted", role)
                print(f"granted the {kind} role {role}: " + (
                    "check passwords, change accounts, allocate, issue and append"
                    if kind == "service" else "read the register (no password hashes); "
                    "it issues nothing itself"))
        print(f"register {redact(args.url)}: " + (f"created, first admin {args.admin}" if made
                                                  else "up to date (it has accounts)"))
        return EXIT_OK
    if what == "serve":
        return _serve(args)
    url = register_url(args)
    with Register.open(url, migrate=not url.startswith(("http:", "https:")),
                       create=False) as reg:
        pw = Passwords(args.password_stdin)
        if what == "audit":
            report = reg.audit_check()
            for p in report.problems:
                print(f"AUDIT TRAIL BROKEN: {p}")
            print(f"audit trail of {redact(reg.url)}: {report.entries} entries, "
                  + ("chain whole" if report.ok else f"{len(report.problems)} problem(s)"))
            held = True
            if args.receipts:
                from bench.app.register.receipts import check_receipts

                found = check_receipts(reg.audit_rows(), args.receipts)
                for p in found.problems:
                    print(f"RECEIPT NOT IN THE TRAIL: {p}")
                print(f"receipts: {found.checked} checked in {found.files} file(s), "
                      + ("every one in the trail" if found.ok
                         else f"{len(found.problems)} not held by the trail"))
                held = found.ok
            return EXIT_OK if report.ok and held else EXIT_BROKEN
        if what == "user":
            return _user(reg, args, pw)
        if what == "settings":
            return _settings(reg, args, pw)
        if what == "withdraw":
            return _withdraw(reg, args, pw)
        if what == "equipment":
            return _equipment(reg, args, pw)
    raise RegisterError(f"unknown register command {what!r}")


def _user(reg: Register, args: argparse.Namespace, pw: Passwords) -> int:
    what = args.user_command
    if what == "list":
        print(f"{'account':<20} {'full name':<24} {'roles':<28} {'state':<9} password")
        for a in reg.accounts():
            state = "active" if a.active else "DISABLED"
            pwd = ("set by an admin: to change" if a.must_change
                   else f"changed {str(a.password_changed_utc)[:10]}")
            print(f"{a.name:<20} {a.full_name:<24} {', '.join(a.roles):<28} {state:<9} {pwd}")
        return EXIT_OK
    if what == "passwd" and args.as_account == args.name:
        old = pw.next(f"current password of {args.name}: ")
        reg.change_password(args.name, old, pw.next(f"new password for {args.name}: "))
        print(f"password of {args.name} changed")
        return EXIT_OK
    by = _acting(reg, args, pw, "admin")
    if what == "add":
        acct = reg.add_account(by, args.name, args.full_name or args.name, args.role,
                               pw.next(f"initial password for {args.name}: "), args.function)
        print(f"account {acct.name} ({acct.full_name}): {', '.join(acct.roles)}; the "
              "password must be changed before it signs or runs (bench register user passwd "
              f"'{acct.name}' --as '{acct.name}')")
    elif what == "passwd":
        reg.reset_password(by, args.name, pw.next(f"new password for {args.name}: "))
        print(f"password of {args.name} set by {by.name}: {args.name} must change it at "
              "the next login")
    elif what in ("disable", "enable"):
        acct = reg.set_active(by, args.name, what == "enable")
        print(f"account {acct.name}: {'active' if acct.active else 'disabled'}")
    else:
        acct = reg.set_role(by, args.name, args.grant or args.revoke, bool(args.grant))
        print(f"account {acct.name}: {', '.join(acct.roles)}")
    return EXIT_OK


def _settings(reg: Register, args: argparse.Namespace, pw: Passwords) -> int:
    from bench.app.register.store import SETTING_DEFAULTS

    if args.settings_command == "list":
        for key in SETTING_DEFAULTS:
            print(f"{key} = {reg.int_setting(key)}")
        return EXIT_OK
    by = _acting(reg, args, pw, "admin")
    reg.set_setting(by, args.key, args.value)
    print(f"setting {args.key} = {args.value}")
    return EXIT_OK


def _serve(args: argparse.Namespace) -> int:
    """The register service in the foreground, until SIGINT/SIGTERM."""
    import os
    import signal

    from waitress import create_server

    from bench.app.register.service import create_app

    url = args.db or os.environ.get("BENCH_REGISTER_DB")
    if not url:
        raise RegisterError("which database? give --db URL or $BENCH_REGISTER_DB (the "
                            "service role's URL)")
    signing = None
    if args.signing_key or args.signing_certificate:
        from pathlib import Path

        from bench.core.lab import Signing

        if not (args.signing_key and args.signing_certificate):
            raise RegisterError("--signing-key and --signing-certificate go together")
        signing = Signing(Path(args.signing_key), Path(args.signing_certificate),
                          args.signing_password_env, origin="bench register serve")
        for f in (signing.key_file, signing.certificate_file):
            if not f.is_file():
                raise RegisterError(f"{f}: not found")
    reg = Register.open(url, migrate=False)
    server = create_server(create_app(reg, signing=signing), host=args.host, port=args.port,
                           threads=8)
    port = server.effective_port
    reg.shown = f"service http://{args.host}:{port}"

    def stop(_sig: int, _frame: FrameType | None) -> None:
        server.close()

    signal.signal(signal.SIGTERM, stop)
    print(f"register service on http://{args.host}:{port} (database {redact(url)})",
          flush=True)
    try:
        server.run()
    except (KeyboardInterrupt, OSError):
        pass
    finally:
        reg.close()
    return EXIT_OK


def _status(e: Equipment, today: dt.date) -> str:
    if e.identity_only:
        return "identity only (no calibration)"
    cal = e.in_force(today)
    dev = e.deviation_on(today)
    if cal is None:
        return "NO CALIBRATION in force"
    if cal.due >= today:
        return "valid"
    return f"DEVIATION until {dev.expires} ({dev.reason})" if dev else "OVERDUE"


def _equipment(reg: Register, args: argparse.Namespace, pw: Passwords) -> int:
    what = args.equipment_command
    today = dt.datetime.now(dt.UTC).date()
    if what == "list":
        items = reg.equipment()
        print(f"{'serial':<22} {'model':<26} {'certificate':<22} {'due':<10}  status")
        for e in items:
            print(f"{e.serial:<22} {e.model:<26} {e.certificate or '-':<22} "
                  f"{e.due.isoformat() if e.due else '-':<10}  {_status(e, today)}")
        print(f"{len(items)} item(s) in {redact(reg.url)}")
        return EXIT_OK
    if what == "history":
        found = next(iter(reg.equipment(args.serial)), None)
        if found is None:
            raise RegisterError(f"equipment {args.serial!r} is not in the inventory")
        e = found
        print(f"{e.serial}: {e.model}; {_status(e, today)} on {today.isoformat()}")
        if e.identity_only:
            print("  identity only: looked up by serial and model, never calibrated")
        for c in e.calibrations:
            print(f"  calibrated {c.calibrated_on or 'not stated'}  {c.certificate:<22} {c.issuer:<20} due "
                  f"{c.due}  {c.as_found()}  (recorded {c.recorded_utc[:19]} by "
                  f"{c.recorded_by})")
        for d in e.deviations:
            print(f"  deviation until {d.expires} by {d.recorded_by} ({d.recorded_utc[:10]}): "
                  f"{d.reason}" + (f"  REVOKED {d.revoked_utc[:19]} by {d.revoked_by}"
                                   if d.revoked_utc else ""))
        return EXIT_OK
    if what == "add":
        by = _acting(reg, args, pw, None)
        reg.add_equipment(by, args.serial, args.model, args.certificate, args.issuer, args.due,
                          args.identity_only, args.calibrated)
        print(f"equipment {args.serial}: {args.model}, " + (
            "identity only (no calibration)" if args.identity_only else
            f"{args.certificate} ({args.issuer}), due {args.due.isoformat()}"))
        return EXIT_OK
    if what == "update":
        by = _acting(reg, args, pw, None)
        err, err_u = _found_error(args.found_error)
        cal = reg.update_equipment(by, args.serial, args.certificate, args.issuer, args.due,
                                   args.calibrated, args.found, err, err_u)
        print(f"equipment {args.serial}: calibrated {cal.calibrated_on or 'not stated'} "
              f"({cal.certificate}, "
              f"{cal.issuer}), due {cal.due}; {cal.as_found()}; the earlier records kept")
        return EXIT_OK
    by = _acting(reg, args, pw, "quality")
    if args.revoke:
        n = reg.revoke_deviation(by, args.serial)
        print(f"deviation for {args.serial}: {n} revoked; the item is overdue again")
        return EXIT_OK
    if not args.reason or not args.expires:
        raise RegisterError("a deviation needs --reason and --expires (or --revoke)")
    reg.add_deviation(by, args.serial, args.reason, args.expires)
    print(f"deviation for {args.serial} until {args.expires.isoformat()}: {args.reason}")
    return EXIT_OK


def _found_error(text: str | None) -> tuple[float | None, float | None]:
    """--found-error V[,U]: the as-found error and its expanded uncertainty."""
    if not text:
        return None, None
    try:
        parts = [float(x) for x in text.split(",")]
    except ValueError:
        raise RegisterError(f"--found-error {text}: a number, or two (V,U)") from None
    if len(parts) > 2:
        raise RegisterError(f"--found-error {text}: V or V,U")
    return parts[0], (parts[1] if len(parts) == 2 else None)


def _withdraw(reg: Register, args: argparse.Namespace, pw: Passwords) -> int:
    by = _acting(reg, args, pw, None)
    rev = reg.withdraw(by, args.number, args.reason)
    print(f"certificate {rev.shown_number}: withdrawn {rev.withdrawn_utc} by {by.name}: "
          f"{rev.withdrawn_reason}")
    return EXIT_OK
